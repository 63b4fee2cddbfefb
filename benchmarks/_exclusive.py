"""Exclusive CPU time per part of a run, for the profilers (``stream_profile.py``,
``fill_level_breakdown.py --parts``): functions are wrapped while a :class:`ExclusiveTimes` is
active (a context manager; every one restored on exit), and a part called inside another is
charged to itself only."""

from __future__ import annotations

import collections
import functools
import importlib
import sys
import time


#: The probe chain every probe env's sensing runs (contacts -> springs -> system -> features), as
#: (module, class or None, function, part) rows for :class:`ExclusiveTimes`: the profilers of
#: ``episode_parts.py`` and ``fill_level_breakdown.py --parts`` add their env's own parts to these.
SENSING_PARTS = (
    ("aas_gym.sim_sensor", "SimAcousticSensor", "sense", "sense (rest)"),
    ("aas_gym.sim_sensor", "SimAcousticSensor", "grasp_contacts", "sense: grasp contacts"),
    ("aas_gym.touching_grasp", None, "touching_grasp", "sense: touching grasp"),
    ("sensors.synthesis.feature_recording", None, "simulate_features", "features (rest: noise, metadata)"),
    ("sensors.synthesis.feature_recording", None, "_build_spectra", "spectra (rest: stream)"),
    ("sensors.synthesis.modal_system", "ModalSystem", "build", "system (rest)"),
    ("sensors.modal.spring_modes", None, "spring_modes", "springs (rest)"),
    ("sensors.modal.spring_modes", "SpringModes", "__init__", "springs: SpringModes (rest)"),
    ("sensors.modal.spring_modes", None, "merge_close_springs", "springs: merge"),
    ("sensors.modal.damping", None, "modal_damping_parts", "system: damping"),
    ("sensors.synthesis.low_rank_modes", None, "low_rank_modes", "system: low-rank modes"),
    ("sensors.synthesis.lti", None, "lti_parts", "system: lti parts (rest)"),
    ("sensors.synthesis.lti", None, "mkl_eig", "system: state eigen-solve"),
    ("sensors.synthesis.drive_spectrum", None, "drive_spectrum", "drive spectrum (rest)"),
    ("sensors.synthesis.window_spectra", None, "window_spectra", "window spectra"),
    ("sensors.mesh.locator", "TetLocator", "locate", "locate points"),
    ("mujoco", None, "mj_step", "physics: mj_step"),
)


class ExclusiveTimes:
    """``seconds`` and ``calls`` per part of ``parts``: (module, class name or None, function,
    part) tuples. ``everywhere``: a module-level function is also wrapped in every module that
    imported it by name (else only in ``module``'s namespace, where its callers look it up)."""

    def __init__(self, parts, clock=time.process_time, everywhere: bool = False) -> None:
        self.parts, self.clock, self.everywhere = tuple(parts), clock, everywhere
        self.seconds = collections.Counter()
        self.calls = collections.Counter()
        self._stack: list[list] = []     # [part, start of its current exclusive stretch]
        self._restore: list = []

    def _timed(self, func, part: str):
        stack, seconds, calls, clock = self._stack, self.seconds, self.calls, self.clock

        @functools.wraps(func)
        def timed(*args, **kwargs):
            t = clock()
            if stack:
                seconds[stack[-1][0]] += t - stack[-1][1]
            stack.append([part, t])
            try:
                return func(*args, **kwargs)
            finally:
                t = clock()
                seconds[part] += t - stack.pop()[1]
                calls[part] += 1
                if stack:
                    stack[-1][1] = t
        return timed

    def _wrap(self, owner, name: str, part: str) -> None:
        raw = owner.__dict__[name] if isinstance(owner, type) else getattr(owner, name)
        if isinstance(raw, functools.cached_property):
            func = raw.func
            raw.func = self._timed(func, part)
            self._restore.append((raw, "func", func))
            return
        kind = type(raw) if isinstance(raw, (classmethod, staticmethod)) else None
        timed = self._timed(raw.__func__ if kind else raw, part)
        holders = [owner]
        if self.everywhere and not isinstance(owner, type):
            holders += [m for m in list(sys.modules.values())
                        if m is not owner and getattr(m, "__dict__", {}).get(name) is raw]
        for holder in holders:
            setattr(holder, name, kind(timed) if kind else timed)
            self._restore.append((holder, name, raw))

    def __enter__(self) -> "ExclusiveTimes":
        for module, cls, name, part in self.parts:
            mod = importlib.import_module(module)
            self._wrap(getattr(mod, cls) if cls else mod, name, part)
        return self

    def __exit__(self, *exc) -> None:
        for owner, name, raw in reversed(self._restore):
            setattr(owner, name, raw)
        self._restore.clear()

    def reset(self) -> None:
        self.seconds.clear()
        self.calls.clear()
