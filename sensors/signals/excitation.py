"""Excitation signals played by the fingertip actuator.

The paper's three excitations, at 44.1 kHz, each looping with a 0.5 s period:

- an impulse of 0.01 s: by default a one-sample click at the start of a 0.01 s slot, whose
  spectrum is flat. ``shape="rect"`` gives a rectangular 0.01 s pulse instead; its spectrum
  has nulls at every multiple of 100 Hz, which is exactly every other 50 Hz feature bin, so it
  is not the default.
- a linear sweep and an exponential sweep from 20 Hz to 10 kHz over 0.5 s.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from .._infra.checks import real_number

KINDS = ("impulse", "linear", "exponential")
# Files written before the names were unified say "fs" and "linear_sweep"/"exponential_sweep".
_LEGACY_KINDS = {"linear_sweep": "linear", "exponential_sweep": "exponential"}
IMPULSE_SHAPES = ("rect", "click")

DEFAULT_FS = 44100
DEFAULT_PERIOD_S = 0.5


#: Most samples one period (or a ``loop``) may hold: 2**26 float64 samples is 0.5 GB, 25 min
#: at 44.1 kHz. Change it here (``sensors.signals.excitation.MAX_SIGNAL_SAMPLES``) for longer ones.
MAX_SIGNAL_SAMPLES = 2**26


def _require_finite_positive(name: str, value: float) -> float:
    value = real_number(value, name)
    if value <= 0.0:
        raise ValueError(f"{name} must be a finite positive number, got {value!r}")
    return value


def _check_samples(name: str, seconds: float, sample_rate_hz: int) -> None:
    """Refuse a signal above :data:`MAX_SIGNAL_SAMPLES` before allocating it."""
    try:  # as floats: 1e308 s overflows to inf here, not in int() or in a message's format
        n = float(seconds) * float(sample_rate_hz)
    except OverflowError:  # an integer beyond float's range
        n = math.inf
    if not n <= MAX_SIGNAL_SAMPLES:
        raise ValueError(f"{name}={seconds!r} s at {sample_rate_hz} Hz is {n:.3g} samples, above the limit of "
                         f"{MAX_SIGNAL_SAMPLES:,} ({MAX_SIGNAL_SAMPLES * 8 / 1e9:.2g} GB): shorten it, or raise "
                         "sensors.signals.excitation.MAX_SIGNAL_SAMPLES")


def _sweep_args(args: dict[str, Any]) -> dict[str, Any]:
    """A sweep constructor's keyword arguments, as the dataclass fields they set."""
    return {k: args[k] for k in ("sample_rate_hz", "duration_s", "period_s", "amplitude", "f0_hz", "f1_hz", "fade_s")}


@dataclass(frozen=True)
class Excitation:
    """One period of a looping actuator excitation.

    Build one with :meth:`impulse`, :meth:`linear_sweep` or :meth:`exponential_sweep`.

    Attributes:
        kind: ``"impulse"``, ``"linear"`` (sweep) or ``"exponential"`` (sweep): the one
            spelling used in datasets, reports, env info and the CLI.
        sample_rate_hz: sample rate in Hz.
        duration_s: active part of each period (pulse length or sweep length), seconds.
        period_s: loop period in seconds (>= ``duration_s``); silence fills the rest.
        amplitude: peak amplitude (full scale is 1.0).
        f0_hz, f1_hz: sweep start and end frequency (sweeps only).
        fade_s: raised-cosine fade-in/out of a sweep, seconds (0 = none).
        shape: impulse shape, ``"click"`` (one sample, flat spectrum) or ``"rect"``
            (a pulse lasting ``duration_s``).
    """

    kind: str
    sample_rate_hz: int = DEFAULT_FS
    duration_s: float = 0.5
    period_s: float = DEFAULT_PERIOD_S
    amplitude: float = 1.0
    f0_hz: float | None = None
    f1_hz: float | None = None
    fade_s: float = 0.0
    shape: str = "click"

    def __post_init__(self) -> None:
        if not isinstance(self.kind, str):
            raise TypeError(f"kind must be one of {KINDS}, got {self.kind!r}")
        object.__setattr__(self, "kind", _LEGACY_KINDS.get(self.kind, self.kind))
        if self.kind not in KINDS:
            raise ValueError(f"kind must be one of {KINDS}, got {self.kind!r}")
        rate = real_number(self.sample_rate_hz, "sample_rate_hz")
        if rate != int(rate) or rate <= 0:
            raise ValueError(f"sample_rate_hz must be a positive integer sample rate in Hz, got {self.sample_rate_hz!r}")
        object.__setattr__(self, "sample_rate_hz", int(rate))
        _require_finite_positive("duration_s", self.duration_s)
        _require_finite_positive("period_s", self.period_s)
        _require_finite_positive("amplitude", self.amplitude)
        real_number(self.fade_s, "fade_s")
        _check_samples("period_s", self.period_s, self.sample_rate_hz)
        if self.period_s < self.duration_s:
            raise ValueError(
                f"period_s ({self.period_s} s) must be >= duration_s ({self.duration_s} s)"
            )
        if round(self.duration_s * self.sample_rate_hz) < 1:
            raise ValueError(f"duration_s={self.duration_s} s is shorter than one sample at sample_rate_hz={self.sample_rate_hz} Hz")
        if self.fade_s < 0 or 2 * self.fade_s > self.duration_s:
            raise ValueError(f"fade_s must be in [0, duration_s / 2], got {self.fade_s!r}")
        if self.kind == "impulse":
            if self.shape not in IMPULSE_SHAPES:
                raise ValueError(f"shape must be one of {IMPULSE_SHAPES}, got {self.shape!r}")
            return
        if self.f0_hz is None or self.f1_hz is None:
            raise ValueError(f"a {self.kind} needs f0_hz and f1_hz")
        nyquist = self.sample_rate_hz / 2.0
        f0, f1 = real_number(self.f0_hz, "f0_hz"), real_number(self.f1_hz, "f1_hz")
        if not (math.isfinite(f0) and math.isfinite(f1)):
            raise ValueError(f"f0_hz and f1_hz must be finite, got {f0!r}, {f1!r}")
        if self.kind == "exponential" and f0 <= 0:
            raise ValueError(f"f0_hz must be > 0 for an exponential sweep, got {f0}")
        if f0 < 0:
            raise ValueError(f"f0_hz must be >= 0, got {f0}")
        if not f0 < f1:
            raise ValueError(f"f0_hz ({f0} Hz) must be below f1_hz ({f1} Hz)")
        if not f1 < nyquist:
            raise ValueError(f"f1_hz ({f1} Hz) must be below the Nyquist frequency sample_rate_hz/2 = {nyquist} Hz")

    # -- constructors ---------------------------------------------------------------------

    @classmethod
    def impulse(
        cls,
        duration_s: float = 0.01,
        *,
        sample_rate_hz: int = DEFAULT_FS,
        period_s: float = DEFAULT_PERIOD_S,
        amplitude: float = 1.0,
        shape: str = "click",
    ) -> Excitation:
        """The paper's impulse of ``duration_s`` (0.01 s) per period: a click opening a
        0.01 s slot (``shape="click"``) or a rectangular pulse filling it (``"rect"``)."""
        return cls("impulse", sample_rate_hz=sample_rate_hz, duration_s=duration_s, period_s=period_s, amplitude=amplitude, shape=shape)

    @classmethod
    def linear_sweep(
        cls,
        f0_hz: float = 20.0,
        f1_hz: float = 10_000.0,
        duration_s: float = 0.5,
        *,
        sample_rate_hz: int = DEFAULT_FS,
        period_s: float = DEFAULT_PERIOD_S,
        amplitude: float = 1.0,
        fade_s: float = 0.0,
    ) -> Excitation:
        """Linear sweep: instantaneous frequency f0 + (f1 - f0) t / T."""
        return cls("linear", **_sweep_args(locals()))

    @classmethod
    def exponential_sweep(
        cls,
        f0_hz: float = 20.0,
        f1_hz: float = 10_000.0,
        duration_s: float = 0.5,
        *,
        sample_rate_hz: int = DEFAULT_FS,
        period_s: float = DEFAULT_PERIOD_S,
        amplitude: float = 1.0,
        fade_s: float = 0.0,
    ) -> Excitation:
        """Exponential sweep: instantaneous frequency f0 (f1 / f0)^(t / T)."""
        return cls("exponential", **_sweep_args(locals()))

    @classmethod
    def by_name(cls, name: str, **kwargs: Any) -> Excitation:
        """Paper-default excitation by name (``impulse``, ``linear``/``linear_sweep``,
        ``exponential``/``exponential_sweep``); keyword arguments override defaults."""
        key = name.lower().replace("-", "_")
        aliases = {"linear_sweep": "linear", "exponential_sweep": "exponential", "exp": "exponential"}
        key = aliases.get(key, key)
        if key not in KINDS:
            raise ValueError(f"unknown excitation {name!r}; known: impulse, linear, exponential")
        return {"impulse": cls.impulse, "linear": cls.linear_sweep, "exponential": cls.exponential_sweep}[key](**kwargs)

    # -- signals --------------------------------------------------------------------------

    @property
    def name(self) -> str:
        """Short name: ``impulse``, ``linear`` or ``exponential``."""
        return self.kind

    @property
    def period_samples(self) -> int:
        """Samples in one loop period."""
        return int(round(self.period_s * self.sample_rate_hz))

    @property
    def active_samples(self) -> int:
        """Samples of the active part (pulse or sweep) at the start of each period."""
        return int(round(self.duration_s * self.sample_rate_hz))

    def instantaneous_frequency_hz(self, t_s: np.ndarray) -> np.ndarray:
        """Analytic instantaneous frequency of a sweep at times ``t_s`` in [0, duration_s]."""
        if self.kind == "impulse":
            raise ValueError("an impulse has no instantaneous frequency")
        t = np.asarray(t_s, dtype=float) / self.duration_s
        if self.kind == "linear":
            return self.f0_hz + (self.f1_hz - self.f0_hz) * t
        return self.f0_hz * (self.f1_hz / self.f0_hz) ** t

    def _phase_rad(self, t_s: np.ndarray) -> np.ndarray:
        T = self.duration_s
        if self.kind == "linear":
            return 2 * np.pi * (self.f0_hz * t_s + (self.f1_hz - self.f0_hz) * t_s**2 / (2 * T))
        log_ratio = math.log(self.f1_hz / self.f0_hz)
        return 2 * np.pi * self.f0_hz * T / log_ratio * np.expm1(t_s / T * log_ratio)

    @property
    def signal(self) -> np.ndarray:
        """One period of the excitation, float64 in [-amplitude, amplitude]."""
        out = np.zeros(self.period_samples)
        n = self.active_samples
        if self.kind == "impulse":
            if self.shape == "rect":
                out[:n] = self.amplitude
            else:
                out[0] = self.amplitude
            return out
        t = np.arange(n) / self.sample_rate_hz
        active = self.amplitude * np.sin(self._phase_rad(t))
        n_fade = int(round(self.fade_s * self.sample_rate_hz))
        if n_fade > 0:
            ramp = 0.5 - 0.5 * np.cos(np.pi * np.arange(n_fade) / n_fade)
            active[:n_fade] *= ramp
            active[n - n_fade:] *= ramp[::-1]
        out[:n] = active
        return out

    def loop_samples(self, duration_s: float) -> int:
        """Samples in :meth:`loop` ``(duration_s)``, validated as it validates them."""
        _require_finite_positive("duration_s", duration_s)
        _check_samples("duration_s", duration_s, self.sample_rate_hz)
        return int(round(duration_s * self.sample_rate_hz))

    def loop(self, duration_s: float) -> np.ndarray:
        """The excitation looped for ``duration_s`` seconds (``round(duration_s * sample_rate_hz)`` samples)."""
        return np.resize(self.signal, self.loop_samples(duration_s))

    # -- metadata -------------------------------------------------------------------------

    def to_dict(self) -> dict[str, Any]:
        """Plain-JSON description (stored with recordings)."""
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Excitation:
        """Inverse of :meth:`to_dict` (also reads files that say ``fs`` for the sample rate)."""
        data = dict(data)
        if "fs" in data and "sample_rate_hz" not in data:
            data["sample_rate_hz"] = data.pop("fs")
        return cls(**data)
