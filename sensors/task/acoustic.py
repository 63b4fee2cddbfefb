"""How an env exposes the acoustic sensor: one :class:`AcousticConfig` for every simulated env
and for ``real.RealGraspEnv``, and the one place that still reads the old spellings of its
fields (keywords beside ``acoustic=``), with a deprecation warning each.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any

import numpy as np

from .._infra.deprecation import warn_deprecated
from ..signals.corruption import CorruptionPipeline
from ..signals.stream_corruption import CorruptedStream
from ..signals.excitation import KINDS, Excitation
from ..signals.features import FEATURE_SCALES, feature_frequencies_hz, scale_features
from ..signals.leak import LeakRecording
from ..signals.observation import AcousticObservation
from ..signals.spectrogram import (N_MELS, mel_spectrogram, n_frames, spectrogram, spectrogram_frequencies_hz)
from ..synthesis.fingertip import FingertipModel
from ..synthesis.modal_system import CONTACT_MODELS
from ..synthesis.passive import PassiveSound
from ..synthesis.stream import ContactTolerance
from .checks import check_choice, check_flag, check_integer, check_number
from .frames import AcousticFrames

__all__ = ["AcousticConfig", "AcousticEnvMixin", "BYTES_PER_SAMPLE", "CADENCES", "DRIVES", "FEATURE_MODES",
           "LEGACY_KEYWORDS", "MAX_HISTORY", "MAX_SAMPLES", "N_FEATURES", "resolve_excitation"]

#: Length of the spectral feature vector (3-10 kHz in 50 Hz steps).
N_FEATURES = int(feature_frequencies_hz().size)

CADENCES = ("action", "every_step", "never", "stream")
#: What ``acoustic`` holds: the paper's 140 FFT amplitudes, an amplitude spectrogram or a mel
#: spectrogram of the recording (``sensors.signals.spectrogram``).
FEATURE_MODES = ("fft140", "spectrogram", "mel")
#: The most frames ``AcousticConfig.history`` may stack.
MAX_HISTORY = 256
#: How the excitation reaches the fingertip (``AcousticConfig.drive``).
DRIVES = ("bandlimited", "foh")

#: Default of ``AcousticConfig.max_samples``: 60 s at 44.1 kHz, the longest recording (or
#: streamed step) an env accepts unless told otherwise.
MAX_SAMPLES = 60 * 44_100
#: Peak memory of simulating one recording, per sample [bytes]: GraspPosition-v0's reset
#: peaks at 29 MB of Python allocations for a 2 s recording and 102 MB for 20 s (tracemalloc),
#: ~92 bytes per added sample (the synthesis holds several float64 arrays of its length).
BYTES_PER_SAMPLE = 100

#: Keywords the envs took beside ``acoustic=`` before it held them: old keyword -> field.
#: Accepted for one more release with a ``DeprecationWarning``.
LEGACY_KEYWORDS = {"excitation": "excitation", "duration_s": "duration_s", "include_waveform": "waveform",
                   "sense_mode": "cadence", "leak": "leak", "fingertip": "fingertip",
                   "stream_tolerance": "stream_tolerance"}


def resolve_excitation(excitation: Excitation | str | dict) -> Excitation:
    """A ``sensors.Excitation`` from an Excitation, a name or a ``to_dict`` dict."""
    if isinstance(excitation, Excitation):
        return excitation
    if isinstance(excitation, str):
        return Excitation.by_name(excitation)
    if isinstance(excitation, dict):
        return Excitation.from_dict(excitation)
    raise TypeError(f"excitation must be a sensors.Excitation, a name {KINDS} or a dict, got {excitation!r}")


def _check_leak(leak: Any) -> None:
    if leak is None or isinstance(leak, (str, os.PathLike, LeakRecording)):
        return
    if isinstance(leak, dict):
        for value in leak.values():
            _check_leak(value)
        return
    raise TypeError(f"leak must be a sensors.LeakRecording, an .npz path, a dict of them by excitation name, "
                    f"or None, got {type(leak).__name__}")


def _leak_key(leak: Any):
    """What identifies a leak for equality: a path by its text, a recording by identity (its
    arrays have no single truth value)."""
    if leak is None or isinstance(leak, (str, os.PathLike)):
        return None if leak is None else os.fspath(leak)
    if isinstance(leak, dict):
        return tuple(sorted((str(k), _leak_key(v)) for k, v in leak.items()))
    return ("recording", id(leak))


@dataclass(frozen=True, eq=False)
class AcousticConfig:
    """How an env exposes the acoustic sensor: one configuration for every simulated env and
    for ``real.RealGraspEnv`` (as dm_control's observables: off until enabled, with noise as a
    separate corruption of the recording). Pass it, or a dict of its fields, as ``acoustic=``.

    Attributes:
        enabled: record at all; ``False`` drops the acoustic entries from the observation
            and costs nothing per step.
        cadence: ``"action"`` (record when the policy asks), ``"every_step"``, ``"never"`` or
            ``"stream"``: the microphone records without a break while the robot moves, the
            excitation looping; each step returns the samples recorded during it under
            ``audio`` and the features of the latest complete excitation period under
            ``acoustic`` (zeros until one is complete). Envs whose actions are probes
            (recognition, grasp position) record every step; streamed, a probe's ``audio`` is
            the ``duration_s`` the hand holds the grasp.
        waveform: add the raw recording (``waveform``, padded or cut to ``duration_s``).
        feature_scale: how the 140 features are scaled: ``"linear"`` (amplitudes, 1e-7 to
            1e-4), ``"db"`` (level relative to 1e-6, tens of dB) or ``"normalized"`` (unit
            norm); see :func:`sensors.signals.features.scale_features`. A policy network next to
            proprioception of order 1 needs ``"db"`` or ``"normalized"``.
        noise_std: std of additive microphone noise in waveform units (simulation only; the
            real microphone brings its own).
        duration_s: length of one recording [s], at least one excitation period.
        excitation: what the actuator plays: a ``sensors.Excitation``, a name (``"impulse"``,
            ``"linear"``, ``"exponential"``) or its ``to_dict`` dict; held as an Excitation.
        leak: simulation only: the rig's actuator-to-microphone leak added to every recording,
            a ``sensors.LeakRecording``, its ``.npz`` path, or a dict of them by excitation name
            (``aas real leak`` records them); ``None``: no leak.
        fingertip: simulation only: the lumped exciter/fingertip drive
            (``sensors.FingertipModel``); ``None``: its defaults at the env's grip force.
        contact_model: simulation only: ``"spring_damper"`` (default: contacts, the fingertip
            pads included, are springs and dampers on the object's modes) or ``"damping"``
            (the paper's model: contacts only damp the free modes).
        drive: simulation only: ``"bandlimited"`` (default: the excitation reaches the
            fingertip as the band-limited signal a sound card plays) or ``"foh"`` (piecewise
            linear between samples, the drive of earlier datasets; spectra low by about
            sinc^4(f/fs)); see ``sensors.synthesis.drive``.
        passive_sound: simulation only, with ``cadence="stream"``: impacts, knocks and slides
            excite the object on top of the drive (``sensors.synthesis.passive``): ``True``,
            ``False``, a ``PassiveSound`` (its rise time and roughness), or ``None`` (default:
            on when streaming; per-action recordings hold a static grasp, nothing changes in them).
        stream_tolerance: simulation only, with ``cadence="stream"``: when contacts count as
            unchanged (``sensors.ContactTolerance``); ``None``: its defaults.
        features: what ``acoustic`` holds (:data:`FEATURE_MODES`): ``"fft140"`` (default, the
            paper's 140 amplitudes at 3000, 3050, ..., 9950 Hz), ``"spectrogram"`` (time x
            163 STFT bins of 43 Hz in 3-10 kHz) or ``"mel"`` (time x 64 HTK-mel bands in
            3-10 kHz) of the recording cut or padded to ``duration_s``; both time-first with
            85 frames for 1 s (``sensors.signals.spectrogram``). Per recording only, not with
            cadence ``"stream"``.
        history: the last N acoustic frames (each entry gets a leading axis of N, oldest
            first, zeros before the first recordings); 1 (default) keeps the single frame's
            shape. A frame enters at each sensor update.
        update_period_s: with cadence ``"every_step"`` or ``"stream"``, the sensor updates
            every this many seconds of simulated (or control) time; between updates the
            observation holds the last value. ``k * dt``: at steps 0, k, 2k, ... of an
            episode; another period T: at each step during which one of the times 0, T, 2T,
            ... falls (the mean rate is 1/T; T below ``dt``: every step). ``None``: every step.
        corruption: a ``sensors.signals.corruption.CorruptionPipeline`` (or a sequence of its
            stages, or of dicts with a ``kind``) applied to each recording before its
            features: gain drift, DC offset, latency and jitter, dropped buffers, clipping,
            background noise; seeded from the env's ``np_random`` (a generator spawned from its
            seed at each reset, so the clean signal's random stream is unchanged). Same in
            simulation and on ``real.RealGraspEnv``. With cadence ``"stream"`` it runs on the
            stream chunk by chunk (``sensors.signals.stream_corruption``: the same samples as
            over the whole stream at once), the ``audio`` and the period features both of the
            corrupted stream. ``None``: none.
        max_samples: the most samples one recording (``duration_s``) or one streamed step
            may hold (default :data:`MAX_SAMPLES`, 60 s at 44.1 kHz; each sample costs about
            :data:`BYTES_PER_SAMPLE` bytes to simulate): a longer one is refused at
            construction with its memory estimate. A limit, not a setting: it does not
            change any output and is not part of the config's equality.
    """

    enabled: bool = True
    cadence: str = "action"
    waveform: bool = False
    feature_scale: str = "linear"
    noise_std: float = 0.0
    duration_s: float = 1.0
    excitation: Excitation = "linear"  # type: ignore[assignment]  # resolved in __post_init__
    leak: Any = None
    fingertip: FingertipModel | None = None
    stream_tolerance: ContactTolerance | None = None
    features: str = "fft140"
    history: int = 1
    update_period_s: float | None = None
    corruption: CorruptionPipeline | None = None
    max_samples: int = MAX_SAMPLES
    contact_model: str = "spring_damper"
    drive: str = "bandlimited"
    passive_sound: Any = None

    def __post_init__(self) -> None:
        for name in ("enabled", "waveform"):  # "no" and "False" are true values: refuse strings
            object.__setattr__(self, name, check_flag(f"acoustic.{name}", getattr(self, name)))
        check_choice("acoustic.cadence", self.cadence, CADENCES)
        check_choice("acoustic.feature_scale", self.feature_scale, FEATURE_SCALES)
        check_choice("acoustic.contact_model", self.contact_model, CONTACT_MODELS)
        check_choice("acoustic.drive", self.drive, DRIVES)
        if not (self.passive_sound is None or isinstance(self.passive_sound, (bool, PassiveSound))):
            raise TypeError("passive_sound must be True, False, None or a sensors.synthesis.passive.PassiveSound, "
                            f"got {type(self.passive_sound).__name__}")
        object.__setattr__(self, "noise_std", check_number("acoustic.noise_std", self.noise_std, 0.0))
        object.__setattr__(self, "duration_s", check_number("acoustic.duration_s", self.duration_s, 0.0,
                                                            low_open=True, unit="s"))
        object.__setattr__(self, "max_samples", check_integer("acoustic.max_samples", self.max_samples, 1))
        if self.cadence == "stream" and self.waveform:
            raise ValueError("waveform=True is for per-action recordings; a streamed observation "
                             "carries its samples under 'audio'")
        object.__setattr__(self, "excitation", resolve_excitation(self.excitation))
        if not self.duration_s >= self.excitation.period_s:
            raise ValueError(f"duration_s must be at least one excitation period ({self.excitation.period_s} s)")
        self.check_samples(self.n_samples, f"a recording of duration_s={self.duration_s:g} s")
        _check_leak(self.leak)
        if self.fingertip is not None and not isinstance(self.fingertip, FingertipModel):
            raise TypeError(f"fingertip must be a sensors.FingertipModel or None, got {type(self.fingertip).__name__}")
        if self.stream_tolerance is not None and not isinstance(self.stream_tolerance, ContactTolerance):
            raise TypeError("stream_tolerance must be a sensors.ContactTolerance or None, "
                            f"got {type(self.stream_tolerance).__name__}")
        self._check_sensing()

    def _check_sensing(self) -> None:
        """The sensor-configuration fields: feature mode, history, update period, corruption."""
        check_choice("acoustic.features", self.features, FEATURE_MODES)
        object.__setattr__(self, "history", check_integer("acoustic.history", self.history, 1, MAX_HISTORY))
        if self.update_period_s is not None:
            object.__setattr__(self, "update_period_s", check_number("acoustic.update_period_s", self.update_period_s,
                                                                     0.0, low_open=True, unit="s"))
            if self.cadence not in ("every_step", "stream"):
                raise ValueError("acoustic.update_period_s paces a sensor that records by itself: it needs cadence "
                                 f"'every_step' or 'stream', got {self.cadence!r}")
        pipeline = CorruptionPipeline.coerce(self.corruption)
        object.__setattr__(self, "corruption", pipeline if pipeline else None)
        if self.cadence == "stream" and self.features != "fft140":
            raise ValueError("acoustic.features other than 'fft140' work on whole recordings: not with cadence 'stream'")
        if self.features != "fft140":
            n_frames(self.n_samples)  # at least one STFT window

    def steps_per_update(self, dt_s: float | None) -> float:
        """The update period in env steps of ``dt_s`` seconds (:class:`AcousticFrames`): 1
        without ``update_period_s``; a whole number when the period is one within float
        rounding (every k-th step), else the fraction (a period of simulated time); ``ValueError``
        for ``dt_s=None`` (an env whose step is one probe, where no period applies)."""
        if self.update_period_s is None:
            return 1
        if dt_s is None:
            raise ValueError("acoustic.update_period_s does not apply to an env whose step is one probe")
        k = self.update_period_s / dt_s
        return int(round(k)) if round(k) >= 1 and abs(k - round(k)) <= 1e-6 * k else k

    def check_samples(self, n_samples: int, what: str) -> None:
        """Refuse, before anything is simulated, ``what`` holding more than :attr:`max_samples`
        samples: ``ValueError`` with the estimate, the limit and how to change either."""
        if n_samples > self.max_samples:
            rate = self.excitation.sample_rate_hz
            size = n_samples * BYTES_PER_SAMPLE
            size = f"{size / 1e9:.1f} GB" if size >= 1e8 else f"{size / 1e6:.0f} MB"
            raise ValueError(f"{what} would hold {n_samples:,} samples at {rate} Hz (limit {self.max_samples:,}, "
                             f"{self.max_samples / rate:g} s; simulating it needs about {size}): shorten it, "
                             "or raise the limit with acoustic={'max_samples': ...}")

    def _key(self) -> tuple:
        return (self.enabled, self.cadence, self.waveform, self.feature_scale, self.noise_std, self.duration_s,
                self.excitation, _leak_key(self.leak), self.fingertip, self.stream_tolerance, self.features,
                self.history, self.update_period_s, self.corruption, self.contact_model, self.drive,
                self.passive_sound)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, AcousticConfig):
            return NotImplemented
        return self._key() == other._key()

    def __hash__(self) -> int:
        return hash(self._key())

    @classmethod
    def coerce(cls, value: "AcousticConfig | dict | None" = None, *, legacy: dict[str, Any] | None = None,
               owner: str = "the env", **defaults: Any) -> "AcousticConfig":
        """The env's config from ``acoustic=`` (``None``, a dict of fields or a config).

        ``legacy``: the old keywords the caller received beside ``acoustic=`` (names in
        :data:`LEGACY_KEYWORDS`); each warns (``DeprecationWarning``, naming ``owner``) and
        sets its field, ``None`` leaving it unset; one that contradicts ``acoustic=`` is a
        ``ValueError``. ``defaults`` are the env's own defaults for fields nobody set."""
        if value is None:
            fields: dict[str, Any] = {}
        elif isinstance(value, cls):
            fields = {f: getattr(value, f) for f in cls.__dataclass_fields__}
        elif isinstance(value, dict):
            unknown = sorted(set(value) - set(cls.__dataclass_fields__))
            if unknown:
                raise TypeError(f"acoustic has no field(s) {unknown}; fields: {list(cls.__dataclass_fields__)}")
            fields = dict(value)
        else:
            raise TypeError(f"acoustic must be an AcousticConfig, a dict or None, got {type(value).__name__}")
        for old, given in (legacy or {}).items():
            name = LEGACY_KEYWORDS[old]
            warn_deprecated(f"{owner}({old}=...)", f"acoustic={{{name!r}: ...}}")
            if given is None:
                continue
            if name in fields and value is not None and not _same(fields[name], given, name):
                raise ValueError(f"acoustic.{name}={fields[name]!r} contradicts the keyword {old}={given!r}")
            fields[name] = given
        return cls(**{**defaults, **fields})

    @property
    def active_cadence(self) -> str:
        """The cadence in effect: ``"never"`` when disabled (nothing is recorded), else
        :attr:`cadence`."""
        return self.cadence if self.enabled else "never"

    @property
    def passive(self) -> PassiveSound | None:
        """The passive-sound model a stream uses (``None``: off); see :attr:`passive_sound`."""
        p = self.passive_sound
        if isinstance(p, PassiveSound):
            return p
        return PassiveSound() if (p is None and self.cadence == "stream") or p is True else None

    @property
    def streaming(self) -> bool:
        """Enabled with cadence ``"stream"``."""
        return self.enabled and self.cadence == "stream"

    @property
    def sample_rate_hz(self) -> int:
        """The excitation's sample rate [Hz]: the recordings'."""
        return self.excitation.sample_rate_hz

    @property
    def n_samples(self) -> int:
        """Samples in one recording."""
        return int(round(self.duration_s * self.excitation.sample_rate_hz))

    def scale_features(self, features: np.ndarray) -> np.ndarray:
        """The amplitude features in this config's ``feature_scale`` (float32)."""
        return scale_features(features, self.feature_scale).astype(np.float32)

    def spaces(self, audio_samples: int | None = None) -> dict:
        """The acoustic entries of the observation space (empty when disabled);
        ``audio_samples``: the length of a streamed step's ``audio``."""
        from gymnasium import spaces  # only env builders need gymnasium

        if not self.enabled:
            return {}
        low = -np.inf if self.feature_scale == "db" else 0.0
        stack = (self.history,) if self.history > 1 else ()
        out = {"acoustic": spaces.Box(low, np.inf, stack + self.frame_shape, np.float32)}
        if self.waveform:
            out["waveform"] = spaces.Box(-np.inf, np.inf, stack + (self.n_samples,), np.float32)
        if self.streaming:
            out["audio"] = spaces.Box(-np.inf, np.inf, stack + (self._audio_samples(audio_samples),), np.float32)
        return out

    @property
    def frame_shape(self) -> tuple[int, ...]:
        """Shape of one ``acoustic`` frame: ``(140,)``, or ``(frames, bins)`` for a spectrogram
        (163 bins) or mel (64 bands) observation."""
        if self.features == "fft140":
            return (N_FEATURES,)
        bins = spectrogram_frequencies_hz(self.sample_rate_hz).size if self.features == "spectrogram" else N_MELS
        return (n_frames(self.n_samples), bins)

    def empty(self, audio_samples: int | None = None) -> dict[str, np.ndarray]:
        """The acoustic entries before the first recording: zeros."""
        if not self.enabled:
            return {}
        out = {"acoustic": self.scale_features(np.zeros(self.frame_shape))}
        if self.waveform:
            out["waveform"] = np.zeros(self.n_samples, np.float32)
        if self.streaming:
            out["audio"] = np.zeros(self._audio_samples(audio_samples), np.float32)
        return out

    def stream_entries(self, features: np.ndarray | None, audio: np.ndarray) -> dict[str, np.ndarray]:
        """The streamed entries: the latest complete period's features (zeros before one)
        and this step's samples."""
        f = np.zeros(N_FEATURES) if features is None else features
        return {"acoustic": self.scale_features(f), "audio": np.asarray(audio, np.float32)}

    def _audio_samples(self, audio_samples: int | None) -> int:
        if audio_samples is None or int(audio_samples) < 1:
            raise ValueError("a streaming env must say how many samples one step records (audio_samples)")
        self.check_samples(int(audio_samples), "one streamed step")
        return int(audio_samples)

    def corrupt(self, recording, rng: np.random.Generator | None):
        """``recording`` through :attr:`corruption` with ``rng`` (the same recording without
        one); ``ValueError`` if a corruption is configured and ``rng`` is None."""
        if self.corruption is None:
            return recording
        if rng is None:
            raise ValueError("acoustic.corruption needs a random generator (the env's corruption_rng)")
        w = self.corruption.apply(recording.waveform, recording.sample_rate_hz, rng)
        return AcousticObservation(w.astype(np.float32), recording.sample_rate_hz, recording.excitation,
                                   recording.start_time_s, dict(recording.metadata, corrupted=True))

    def corrupted_stream(self, rng: np.random.Generator | None, excitation=None):
        """A new ``sensors.signals.CorruptedStream`` of :attr:`corruption` for a stream that
        starts now, looping ``excitation`` (default :attr:`excitation`; its period frames the
        features), its generators spawned from ``rng`` (the env's corruption_rng); ``None``
        without a corruption."""
        if self.corruption is None:
            return None
        if rng is None:
            raise ValueError("acoustic.corruption needs a random generator (the env's corruption_rng)")
        ex = self.excitation if excitation is None else excitation
        return CorruptedStream(self.corruption, ex.sample_rate_hz, rng, ex.period_samples, ex.period_s)

    @property
    def needs_waveform(self) -> bool:
        """Whether a recording's samples are needed (observed, corrupted, or a spectrogram made
        of them); otherwise its 140 features are enough (the closed form, no audio)."""
        return self.waveform or self.corruption is not None or self.features != "fft140"

    def entries(self, recording, rng: np.random.Generator | None = None) -> dict[str, np.ndarray]:
        """The acoustic entries of a ``sensors.AcousticObservation`` (one frame): after
        :meth:`corrupt` (with ``rng``), its features in :attr:`features` mode and, with
        ``waveform``, its samples zero-padded or cut to ``duration_s``. Without
        :attr:`needs_waveform`, a features-only recording (``sensors.synthesis.FeatureObservation``)."""
        if not self.enabled:
            return {}
        if not self.needs_waveform:
            return {"acoustic": self.scale_features(recording.features())}
        recording = self.corrupt(recording, rng)
        n = int(round(self.duration_s * recording.sample_rate_hz))
        w = np.zeros(n, np.float32)
        m = min(n, recording.waveform.size)
        w[:m] = recording.waveform[:m]
        if self.features == "fft140":
            features = recording.features()
        elif self.features == "spectrogram":
            features = spectrogram(w, recording.sample_rate_hz)
        else:
            features = mel_spectrogram(w, recording.sample_rate_hz)
        out = {"acoustic": self.scale_features(features)}
        if self.waveform:
            out["waveform"] = w
        return out


def _same(a: Any, b: Any, field: str) -> bool:
    """Whether two values of a field say the same (an excitation by name or object alike)."""
    if field == "excitation":
        return resolve_excitation(a) == resolve_excitation(b)
    if field == "leak":
        return _leak_key(a) == _leak_key(b)
    return a == b


class AcousticEnvMixin:
    """The views an env with an ``acoustic`` (:class:`AcousticConfig`) attribute gives of it,
    written once for the simulated envs (``aas_gym``) and the real one (``real``)."""

    acoustic: AcousticConfig

    @property
    def excitation(self) -> Excitation:
        """What the actuator plays (``acoustic.excitation``)."""
        return self.acoustic.excitation

    @property
    def duration_s(self) -> float:
        """Length of one recording [s] (``acoustic.duration_s``)."""
        return self.acoustic.duration_s

    @property
    def cadence(self) -> str:
        """When the env records: ``acoustic.cadence``, or ``"never"`` when the sensor is off."""
        return self.acoustic.active_cadence

    @property
    def sense_mode(self) -> str:
        """Deprecated: :attr:`cadence`."""
        warn_deprecated(f"{type(self).__name__}.sense_mode", "cadence")
        return self.cadence

    # --- history, update period, corruption (AcousticConfig's sensor configuration) ----------
    def _init_acoustic_frames(self, audio_samples: int | None, dt_s: float | None) -> None:
        """The env's :class:`AcousticFrames` (call once in ``__init__``); ``dt_s``: the env's
        step [s], None for an env whose step is one probe."""
        self.acoustic_frames = AcousticFrames(self.acoustic.empty(audio_samples), self.acoustic.history,
                                              self.acoustic.steps_per_update(dt_s))
        self.corruption_rng: np.random.Generator | None = None

    def _reset_acoustic(self) -> dict[str, np.ndarray]:
        """At ``reset`` (after seeding): a new corruption generator spawned from ``np_random``'s
        seed (the clean random stream is not drawn from), an empty history; its observation."""
        if self.acoustic.corruption is not None:
            seq = getattr(self.np_random.bit_generator, "seed_seq", None)
            self.corruption_rng = np.random.default_rng(seq.spawn(1)[0] if seq is not None
                                                        else self.np_random.integers(2**63))
        return self.acoustic_frames.reset()

    def _acoustic_due(self) -> bool:
        """Whether the sensor updates this step (``acoustic.update_period_s``); call once per step."""
        return self.acoustic_frames.due()

    def _recording_entries(self, recording) -> dict[str, np.ndarray]:
        """A recording's frame (corrupted with :attr:`corruption_rng`) pushed to the history;
        the observation's acoustic entries."""
        return self.acoustic_frames.push(self.acoustic.entries(recording, rng=self.corruption_rng))
