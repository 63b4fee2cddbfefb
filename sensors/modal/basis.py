"""What synthesis, the simulated sensor and calibration need of a modal model, and the one way
to see a model in another material (:func:`with_material`).

``ModalBasis`` is the interface: a ``sensors.ModalModel``, a :class:`MaterialView` of one,
or any user object with these members works everywhere a modal model is taken.
"""

from __future__ import annotations

import math
from typing import Protocol, runtime_checkable

import numpy as np

from .._infra.checks import holds_bool
from .damping import modal_damping_matrix, within_surface_distance_m

#: Object-frame points farther than this from the origin [m] are refused: no object is that
#: large, and squared distances of points near 1e308 overflow the point location.
MAX_POINT_COORDINATE_M = 1e6

#: An (n, 3) float64 ndarray (what every caller inside the synthesis passes, about 5 times per
#: contact set) is accepted by one reduction, max |p| <= MAX_POINT_COORDINATE_M (False for NaN
#: and inf), and copied by the same ``astype``; anything else, or a failing array, takes the
#: general checks below (which raise their own errors).  False: the general checks always
#: (the reference; ``tests/test_episode_glue.py``).  Read at each call.
FAST_POINT_CHECKS = True


def check_points_m(points_m) -> np.ndarray:
    """``points_m`` as an (n, 3) float array of object-frame points [m]; TypeError for
    non-numbers (booleans, strings), ValueError for another shape, NaN/inf or a coordinate
    beyond :data:`MAX_POINT_COORDINATE_M`."""
    if FAST_POINT_CHECKS and type(points_m) is np.ndarray and points_m.dtype == np.float64 \
            and points_m.ndim == 2 and points_m.shape[1] == 3 \
            and np.abs(points_m).max(initial=0.0) <= MAX_POINT_COORDINATE_M:
        return points_m.astype(np.float64)
    p = np.asarray(points_m)
    if p.dtype.kind not in "iuf" or holds_bool(points_m):
        raise TypeError(f"points_m must be numbers [m], got dtype {p.dtype}")
    p = np.atleast_2d(p.astype(np.float64))
    if p.ndim != 2 or p.shape[1] != 3:
        raise ValueError(f"points_m must have shape (n, 3) or (3,), got {np.shape(points_m)}")
    if not np.all(np.isfinite(p)):
        raise ValueError("points_m contains non-finite values")
    if p.size and np.abs(p).max() > MAX_POINT_COORDINATE_M:
        raise ValueError(f"points_m has a coordinate of {np.abs(p).max():.3g} m, beyond {MAX_POINT_COORDINATE_M:g} m: "
                         "object-frame points in metres?")
    return p
from ..materials.solids import Material, get_material


@runtime_checkable
class ModalBasis(Protocol):
    """Mass-normalised elastic modes of one object.

    Members (SI units):
        frequencies_hz, angular_frequencies_rad_s: (r,) undamped natural frequencies.
        material: a ``sensors.Material`` (alpha [1/s], beta [s], gamma [s/m] for damping).
        mode_shapes_at(points_m): (n, 3, r) mode shapes at points of the object frame.

    Optional members the code uses when present: ``surface_distance_m(points_m)`` (contacts
    off the surface are refused) and ``within_surface_distance_m(points_m, limit_m)`` (the same
    decisions, cheaper: ``sensors.modal.damping.within_surface_distance_m``), ``mass_kg`` (the fingertip drive model), ``n_modes``,
    ``decay_rates_per_s`` (decay rates without contacts [1/s]), ``added_damping_per_s`` ((r,)
    modal damping [1/s] added to the diagonal alpha + beta w^2, e.g. a liquid's), and a
    ``with_material(material)`` method, which :func:`with_material` calls, for models that know
    better than a :class:`MaterialView` (a ``ModalModel`` rebuilds on a new Poisson ratio; a
    filled container, ``material_scales_modes = False``, rescales its wall but not its liquid).
    """

    frequencies_hz: np.ndarray
    angular_frequencies_rad_s: np.ndarray
    material: Material

    def mode_shapes_at(self, points_m) -> np.ndarray: ...


def band_text(frequencies_hz) -> str:
    """'f_min-f_max Hz' of a mode set, or 'no modes' (for one-line descriptions)."""
    f = np.asarray(frequencies_hz)
    return f"{f[0]:.0f}-{f[-1]:.0f} Hz" if len(f) else "no modes"


def material_scaling(old: Material, new: Material) -> tuple[float, float]:
    """``(frequency_scale, shape_scale)`` taking modes in ``old`` to modes in ``new`` exactly.

    With the Poisson ratio kept, K scales with E and M with the density: eigenvalues scale by
    (E'/rho') / (E/rho) with the same shapes, which mass-normalised scale by sqrt(rho/rho').
    A different Poisson ratio changes the shapes: ``ValueError``.
    """
    if not math.isclose(new.poisson_ratio, old.poisson_ratio, rel_tol=0, abs_tol=1e-12):
        raise ValueError(f"Poisson ratio {old.poisson_ratio} -> {new.poisson_ratio} changes the mode shapes: "
                         "this needs a new FEM solve")
    c2 = (new.youngs_modulus_pa / new.density_kg_m3) / (old.youngs_modulus_pa / old.density_kg_m3)
    return math.sqrt(c2), math.sqrt(old.density_kg_m3 / new.density_kg_m3)


class MaterialView:
    """A modal model seen in another material of the same Poisson ratio: exact, no new solve
    (:func:`material_scaling`). Damping comes from the new material; shapes, surface and
    everything not material-dependent are the base model's. What :func:`with_material` returns
    when a rescaling is exact; it shares the base's arrays (no copy per material).
    """

    def __init__(self, base: ModalBasis, material: Material) -> None:
        if isinstance(base, MaterialView):  # a view of a view is a view of the base
            base = base.base
        if getattr(base, "material_scales_modes", True) is False:
            raise TypeError(f"a {type(base).__name__} does not rescale exactly with its material: "
                            "use sensors.with_material(model, material)")
        self.base = base
        self.material = get_material(material)
        self.frequency_scale, self.shape_scale = material_scaling(base.material, self.material)
        self.angular_frequencies_rad_s = np.asarray(base.angular_frequencies_rad_s, float) * self.frequency_scale
        self.frequencies_hz = self.angular_frequencies_rad_s / (2 * np.pi)

    def mode_shapes_at(self, points_m) -> np.ndarray:
        return np.asarray(self.base.mode_shapes_at(points_m)) * self.shape_scale

    def surface_distance_m(self, points_m) -> np.ndarray:
        return self.base.surface_distance_m(points_m)

    def within_surface_distance_m(self, points_m, limit_m: float) -> np.ndarray:
        return within_surface_distance_m(self.base, points_m, limit_m)

    @property
    def mass_kg(self) -> float:
        return float(self.base.mass_kg) * self.material.density_kg_m3 / self.base.material.density_kg_m3

    @property
    def n_modes(self) -> int:
        return int(self.angular_frequencies_rad_s.size)

    @property
    def eigenvalues(self) -> np.ndarray:
        """w^2 [rad^2/s^2]."""
        return self.angular_frequencies_rad_s ** 2

    @property
    def decay_rates_per_s(self) -> np.ndarray:
        """Rayleigh decay rates (alpha + beta w^2) / 2 [1/s] of the new material."""
        return self.material.decay_rate(self.angular_frequencies_rad_s)

    def damping_matrix(self, contacts=()) -> np.ndarray:
        """C_m of the new material (see :func:`sensors.modal_damping_matrix`)."""
        return modal_damping_matrix(self, contacts)

    def with_material(self, material) -> ModalBasis:
        """The base model in ``material`` (:func:`with_material`)."""
        return with_material(self.base, material)

    def __repr__(self) -> str:
        return f"MaterialView({self.base!r}, material={self.material.name!r})"

    def __getattr__(self, name: str):
        # Only for attributes not found normally. ``base`` itself, and dunders, are never
        # forwarded: copy/pickle look them up on an instance made without __init__ (no
        # ``base`` yet), where forwarding would recurse forever.
        if name == "base" or (name.startswith("__") and name.endswith("__")):
            raise AttributeError(name)
        if name in ("save", "nodes_m", "mode_shapes", "elements", "mode_matrix", "assemble_matrices"):
            # material-dependent data of the base (or a file of it) must not pass as this view's
            raise AttributeError(f"a MaterialView has no {name!r}: build the model in {self.material.name} instead")
        return getattr(self.base, name)


def with_material(model: ModalBasis, material) -> ModalBasis:
    """The one way to change a modal model's material: ``model`` in ``material`` (a
    :class:`~sensors.Material` or a built-in name), exact.

    With the Poisson ratio kept, a :class:`MaterialView` (no new solve, no copy of the shapes).
    A model with its own ``with_material`` method answers for itself, with that same meaning: a
    ``ModalModel`` gives the view, or on a new Poisson ratio rebuilds a bar, tube or rod; a filled
    container rescales its wall but not its liquid. Any other model on a new Poisson ratio:
    ``ValueError``. The methods are this function; call either.
    """
    material = get_material(material)
    if isinstance(model, MaterialView):  # a view of a view is a view of the base
        model = model.base
    own = getattr(model, "with_material", None)
    if callable(own):
        return own(material)
    return MaterialView(model, material)

