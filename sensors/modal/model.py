"""ModalModel: the elastic modes of one solid object, built once and cached.

This module holds the result and its queries: mode shapes at any point on or in the object,
interpolated with the element shape functions (not snapped to vertices), distance to the
surface and outward normals. Building (mesh -> K, M -> modes, cached) is
:mod:`sensors.modal.build`, point location :mod:`sensors.mesh.locator`, files
:mod:`sensors.modal.io`.
"""

from __future__ import annotations

import functools
import math
from pathlib import Path

import numpy as np

from .._infra import cache as cache_mod
from .._infra.checks import real_number
from . import build as modal_build, io as modal_io
from .damping import modal_damping_matrix
from ..fem.assembly import assemble, shape_functions
from ..materials.solids import get_material
from ..mesh.prisms import bar_mesh, rod_mesh, tube_mesh
from ..mesh.tets import MeshError, TetMesh, tet_volumes
from ..mesh.tetwild import tetrahedralize_surface, validate_surface
from .basis import MaterialView, band_text, check_points_m
from ..mesh.locator import TetLocator, closest_points_on_triangles  # noqa: F401  (re-exported)

#: Sizes [m] of what a gripper holds: a mesh outside is probably in another unit (``scale=``).
MIN_OBJECT_SIZE_M, MAX_OBJECT_SIZE_M = 2e-3, 2.0

__all__ = ["ModalModel", "closest_points_on_triangles"]


#: Sizes [m] of a bar, tube or rod that ``ModalModel.bar/tube/rod`` builds: 1 um .. 10 m
#: (beyond them the mesh's numbers degenerate or its eigen-solve never ends).
STRUCTURED_DIMENSION_RANGE_M = (1e-6, 10.0)

class ModalModel:
    """Elastic modes of a free solid: frequencies, damping and mass-normalized mode shapes.

    Build with :meth:`bar`, :meth:`tube`, :meth:`rod` or :meth:`from_mesh`; or construct
    directly from arrays (e.g. a tiny hand-made model in a test)::

        ModalModel(nodes_m, elements, frequencies_hz, mode_shapes, material, element="p1")

    Args:
        nodes_m: (n_nodes, 3) node coordinates [m] in the object frame.
        elements: (m, 4) linear or (m, 10) quadratic tets (VTK node order), positively oriented.
        frequencies_hz: (r,) ascending elastic natural frequencies [Hz].
        mode_shapes: (n_nodes, 3, r) mass-normalized displacement of each mode at each node
            (U^T M U = I, so units m / sqrt(kg)).
        material: A :class:`~sensors.Material` or a built-in material name.
        element: "p1" or "p2" (default: from the element array width).
        metadata: Free-form description (shape kind, dimensions, build options...).
    """

    def __init__(self, nodes_m, elements, frequencies_hz, mode_shapes, material, element: str | None = None,
                 metadata: dict | None = None):
        self.nodes_m = np.ascontiguousarray(nodes_m, dtype=np.float64)
        self.elements = np.ascontiguousarray(elements, dtype=np.int64)
        self.frequencies_hz = np.ascontiguousarray(frequencies_hz, dtype=np.float64).reshape(-1)
        self.mode_shapes = np.ascontiguousarray(mode_shapes, dtype=np.float64)
        self.material = get_material(material)
        if element is None:
            element = {4: "p1", 10: "p2"}.get(self.elements.shape[1], "?")
        self.element = element.lower()
        n_el = {"p1": 4, "p2": 10}.get(self.element)
        if n_el is None or self.elements.ndim != 2 or self.elements.shape[1] != n_el:
            raise ValueError(f"elements of shape {self.elements.shape} do not match element {element!r}")
        if self.nodes_m.ndim != 2 or self.nodes_m.shape[1] != 3:
            raise ValueError(f"nodes_m must have shape (n, 3), got {self.nodes_m.shape}")
        r = len(self.frequencies_hz)
        if self.mode_shapes.shape != (len(self.nodes_m), 3, r):
            raise ValueError(f"mode_shapes must have shape {(len(self.nodes_m), 3, r)}, got {self.mode_shapes.shape}")
        if not (np.all(np.isfinite(self.frequencies_hz)) and np.all(np.isfinite(self.mode_shapes))
                and np.all(np.isfinite(self.nodes_m))):
            raise ValueError("frequencies_hz, mode_shapes and nodes_m must be finite")
        if r and (np.any(np.diff(self.frequencies_hz) < 0) or self.frequencies_hz[0] <= 0):
            raise ValueError("frequencies_hz must be positive and ascending")
        self.metadata = dict(metadata or {})
        self.metadata.setdefault("material", self.material.name)
        self.metadata.setdefault("element", self.element)
        self._locator: TetLocator | None = None

    # ------------------------------------------------------------------ modal quantities

    @property
    def n_modes(self) -> int:
        """Number of elastic modes r."""
        return len(self.frequencies_hz)

    @property
    def angular_frequencies_rad_s(self) -> np.ndarray:
        """Natural angular frequencies w = 2 pi f [rad/s]."""
        return 2.0 * np.pi * self.frequencies_hz

    @property
    def eigenvalues(self) -> np.ndarray:
        """w^2 [rad^2/s^2], the diagonal of the modal stiffness (modal mass is 1)."""
        return self.angular_frequencies_rad_s**2

    @property
    def decay_rates_per_s(self) -> np.ndarray:
        """Modal decay rates from Rayleigh damping, (alpha + beta w^2) / 2 [1/s]."""
        return self.material.decay_rate(self.angular_frequencies_rad_s)

    @property
    def kind(self) -> str:
        """"bar", "tube", "rod" or "mesh"."""
        return self.metadata.get("kind", "mesh")

    @property
    def dimensions_m(self) -> dict:
        """Shape parameters, e.g. {"length_m": .2, "width_m": .025, "height_m": .025}."""
        return dict(self.metadata.get("dimensions_m", {}))

    @functools.cached_property
    def mass_kg(self) -> float:
        """Total mass [kg] (density times the meshed volume; summed once, every recording reads it)."""
        return float(self.material.density_kg_m3 * tet_volumes(self.nodes_m, self.elements).sum())

    def describe(self) -> str:
        """One-line human description."""
        dims = ", ".join(f"{k}={v * 1000:.4g} mm" for k, v in self.dimensions_m.items())
        band = band_text(self.frequencies_hz)
        return (f"{self.kind} ({dims}) of {self.material.name}, {self.element.upper()} "
                f"{len(self.elements)} tets, {self.n_modes} modes {band}")

    def __repr__(self) -> str:
        return f"ModalModel<{self.describe()}>"

    def assemble_matrices(self):
        """Re-assemble (K, M) on this model's mesh (for checks such as U^T M U = I)."""
        return assemble(self.nodes_m, self.elements, self.material, self.element)

    def mode_matrix(self) -> np.ndarray:
        """Mode shapes as a (3 n_nodes, r) matrix in node-major dof order."""
        return self.mode_shapes.reshape(-1, self.n_modes)

    # ------------------------------------------------------------------ geometry queries

    @property
    def locator(self) -> TetLocator:
        """Point location in this model's mesh (spatial indexes built on first use)."""
        if self._locator is None:
            self._locator = TetLocator(self.nodes_m, self.elements)
        return self._locator

    @staticmethod
    def _points(points_m) -> np.ndarray:
        return check_points_m(points_m)

    def mode_shapes_at(self, points_m) -> np.ndarray:
        """Mode shapes at arbitrary points, interpolated with the element shape functions.

        Points inside the object use their containing element; points on or off the surface
        are projected onto the nearest boundary triangle first (use
        :meth:`surface_distance_m` to reject points far from the object).

        Args:
            points_m: (n, 3) points [m] in the object frame.

        Returns:
            (n, 3, r) displacement of each mode at each point [m / sqrt(kg)].
        """
        p = self._points(points_m)
        tet, bary = self.locator.locate(p)
        N = shape_functions(bary, self.element)  # (n, n_el)
        return np.einsum("pa,paxr->pxr", N, self.mode_shapes[self.elements[tet]])

    def surface_distance_m(self, points_m) -> np.ndarray:
        """Unsigned distance [m] from each point to the (faceted) surface of the mesh, (n,)."""
        p = self._points(points_m)
        return self.locator.closest_surface(p)[2]

    def within_surface_distance_m(self, points_m, limit_m: float) -> np.ndarray:
        """Whether each point lies within ``limit_m`` [m] of the surface, (n,) bool: the
        decisions of ``surface_distance_m(points_m) <= limit_m``, most settled by bounds
        without the full distance query (``sensors.mesh.locator.CENTROID_BOUNDS``)."""
        return self.locator.within_surface_distance(self._points(points_m), limit_m)

    def surface_normal_at(self, points_m) -> np.ndarray:
        """Outward unit surface normal at the surface point nearest to each point, (n, 3).

        Faceted for general meshes; exact (radial) on the curved faces of tubes and rods,
        whose facets are only a polygonal approximation of the cylinder.
        """
        p = self._points(points_m)
        _, face, _ = self.locator.closest_surface(p)
        n = self.locator.surface_data()["normal"][face].copy()
        if self.kind in ("tube", "rod"):
            radial = np.zeros_like(p)
            radial[:, 1:] = p[:, 1:]
            r = np.linalg.norm(radial, axis=1)
            curved = (np.abs(n[:, 0]) < 0.5) & (r > 0)
            sign = np.sign(np.einsum("ij,ij->i", n, radial))
            n[curved] = (radial[curved] / r[curved, None]) * sign[curved, None]
        return n

    def with_material(self, material, **options):
        """This object in another material, as :func:`sensors.with_material` (which calls this).

        With the same Poisson ratio, K scales with E and M with the density, so the modes are
        exact without a new solve: a :class:`~sensors.MaterialView` (frequencies times
        sqrt((E'/rho') / (E/rho)), mass-normalized shapes times sqrt(rho / rho')). A different
        Poisson ratio changes the mode shapes: bars, tubes and rods are rebuilt with the stored
        options (``options`` override them); other meshes raise.
        """
        material = get_material(material)
        if math.isclose(material.poisson_ratio, self.material.poisson_ratio, rel_tol=0, abs_tol=1e-12):
            return MaterialView(self, material)
        builders = {"bar": ModalModel.bar, "tube": ModalModel.tube, "rod": ModalModel.rod}
        if self.kind not in builders:
            raise ValueError("a different Poisson ratio needs a new solve; rebuild the model with from_mesh")
        opts = {k: self.metadata[k] for k in modal_build.RESULT_OPTIONS if k in self.metadata}
        opts.update(options)
        return builders[self.kind](**self.dimensions_m, material=material, **opts)

    def damping_matrix(self, contacts):
        """Modal damping matrix (r, r) for the given contacts (see :mod:`sensors.modal.damping`)."""
        return modal_damping_matrix(self, contacts)

    # ------------------------------------------------------------------ persistence

    def save(self, path) -> Path:
        """Write the model to an ``.npz`` file (no pickle, atomically); returns the path."""
        return modal_io.save(self, path)

    @classmethod
    def load(cls, path) -> "ModalModel":
        """Read a model written by :meth:`save`."""
        return modal_io.load(cls, path)

    # ------------------------------------------------------------------ builders

    @classmethod
    def bar(cls, length_m: float, width_m: float, height_m: float, material, **options) -> "ModalModel":
        """Box along x (width along y, height along z), centred at the origin.

        Options: see :meth:`from_tet_mesh` (element, max_frequency_hz, resolution,
        element_size_m, cache, cache_dir, progress).
        """
        return cls._build_structured("bar", bar_mesh, dict(length_m=length_m, width_m=width_m, height_m=height_m),
                                     material, options)

    @classmethod
    def tube(cls, length_m: float, outer_radius_m: float, inner_radius_m: float, material, **options) -> "ModalModel":
        """Hollow cylinder along x, centred at the origin. Options as :meth:`bar`."""
        return cls._build_structured("tube", tube_mesh, dict(length_m=length_m, outer_radius_m=outer_radius_m,
                                                             inner_radius_m=inner_radius_m), material, options)

    @classmethod
    def rod(cls, length_m: float, radius_m: float, material, **options) -> "ModalModel":
        """Solid cylinder along x, centred at the origin. Options as :meth:`bar`."""
        return cls._build_structured("rod", rod_mesh, dict(length_m=length_m, radius_m=radius_m), material, options)

    @classmethod
    def from_mesh(cls, mesh, material, *, scale: float | None = None, **options) -> "ModalModel":
        """Any watertight ``trimesh.Trimesh`` (metres), tetrahedralized with pytetwild.

        The mesh is used in its own frame. Options as :meth:`bar`; ``element_size_m``
        defaults to a quarter of the smallest bounding-box extent. ``scale`` multiplies the
        vertices first (``1e-3`` for a mesh in millimetres); without it, a mesh larger than
        2 m or smaller than 2 mm is refused as probably in the wrong unit.
        """
        opts = modal_build.options(options)
        material = get_material(material)
        surface = validate_surface(mesh)
        size = float(np.ptp(np.asarray(surface.vertices), axis=0).max())
        if scale is None and not MIN_OBJECT_SIZE_M <= size <= MAX_OBJECT_SIZE_M:
            hint = "1e-3 if it is in millimetres" if size > MAX_OBJECT_SIZE_M else "1e3 if its unit is 1000 times too large"
            raise MeshError(f"the mesh is {size:.3g} m across, outside {MIN_OBJECT_SIZE_M * 1e3:g} mm .. "
                            f"{MAX_OBJECT_SIZE_M:g} m: is it in another unit? Pass scale= ({hint}); scale=1 "
                            "keeps it as it is")
        if scale is not None:
            if not (np.isfinite(scale) and scale > 0):
                raise MeshError(f"scale must be a finite positive number, got {scale!r}")
            if scale != 1:
                surface = surface.copy()
                surface.apply_scale(float(scale))
        v = np.asarray(surface.vertices, dtype=np.float64)
        f = np.asarray(surface.faces, dtype=np.int64)
        key = cache_mod.content_key("modal-mesh", v, f, material.to_dict(), modal_build.key_options(opts))

        def make():
            return tetrahedralize_surface(surface, element_size_m=opts["element_size_m"],
                                          resolution=opts["resolution"], cache=opts["cache"],
                                          cache_dir=opts["cache_dir"], max_dof=opts["max_dof"])

        extents = np.ptp(v, axis=0)
        meta = {"kind": "mesh", "dimensions_m": {"extent_x_m": float(extents[0]), "extent_y_m": float(extents[1]),
                                                 "extent_z_m": float(extents[2])}}
        return modal_build.build(cls, key, make, material, opts, meta)

    @classmethod
    def from_cache_key(cls, key: str, **options) -> "ModalModel | None":
        """The model cached under ``key`` (a built model's ``metadata["cache_key"]``), or None
        if it is not in the cache (or unreadable there); options as :meth:`from_tet_mesh`."""
        return modal_build.cached(cls, key, modal_build.options(options))

    @classmethod
    def from_tet_mesh(cls, tet_mesh: TetMesh, material, **options) -> "ModalModel":
        """Build from an existing linear :class:`~sensors.mesh.tets.TetMesh`.

        Options:
            element: "p2" (default, quadratic tets) or "p1" (linear; locks in bending).
            max_frequency_hz: Band limit [Hz], default 22050 (Nyquist of 44.1 kHz).
            resolution: Multiplies the number of elements in each direction (default 1).
            element_size_m: Target element size [m] (overrides the shape's default).
            cache: Use the on-disk cache (default True).
            cache_dir: Cache directory (default $AAS_GYM_CACHE or ~/.cache/aas_gym).
            progress: None (a progress bar appears if the build takes over a second),
                True (always) or False (never).
            max_dof: refuse, before meshing, a model larger than this many degrees of
                freedom (default ``sensors.mesh.tets.DEFAULT_MAX_DOF`` = 300,000; ``None``: no
                limit) with a ``MeshError`` that says how to coarsen it.
        """
        opts = modal_build.options(options)
        material = get_material(material)
        key = cache_mod.content_key("modal-tets", tet_mesh.digest(), material.to_dict(), modal_build.key_options(opts))
        meta = {"kind": tet_mesh.kind, "dimensions_m": dict(tet_mesh.dimensions_m)}
        return modal_build.build(cls, key, lambda: tet_mesh, material, opts, meta)

    @classmethod
    def _build_structured(cls, kind, mesher, dims, material, options) -> "ModalModel":
        lo, hi = STRUCTURED_DIMENSION_RANGE_M
        for name, value in dims.items():
            if not lo <= real_number(value, name) <= hi:
                raise MeshError(f"{kind} {name}={value!r} is outside {lo:g} .. {hi:g} m (a unit mix-up?); no "
                                "structured model is built outside it "
                                "(sensors.modal.model.STRUCTURED_DIMENSION_RANGE_M)")
        opts = modal_build.options(options)
        material = get_material(material)
        # The key needs no meshing: a cached build is just a file read.
        key = cache_mod.content_key("modal-" + kind, dims, material.to_dict(), modal_build.key_options(opts))

        def make():
            return mesher(**dims, element_size_m=opts["element_size_m"], resolution=opts["resolution"],
                          max_dof=opts["max_dof"])

        return modal_build.build(cls, key, make, material, opts, {"kind": kind, "dimensions_m": {k: float(v) for k, v in dims.items()}})
