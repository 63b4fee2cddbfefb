"""ModalModel: the elastic modes of one solid object, built once and cached.

Build: tet mesh (structured for bar/tube/rod, pytetwild otherwise) -> P2 (default) or P1
elements -> K, M -> elastic modes up to ``max_frequency_hz`` -> mass-normalized mode shapes.
Query: mode shapes at any point on or in the object, interpolated with the element shape
functions (not snapped to vertices), distance to the surface and outward normals.
"""

from __future__ import annotations

import json
import logging
import math
import time
from pathlib import Path

import numpy as np

from . import cache as cache_mod
from .atomic import atomic_open
from .damping import modal_damping_matrix
from .eigen import solve_modes
from .fem import assemble, shape_functions
from .materials import Material, get_material
from .modal_basis import material_scaling
from .meshing import (
    TetMesh,
    bar_mesh,
    boundary_faces,
    check_tet_quality,
    quadratic_mesh,
    rod_mesh,
    tet_volumes,
    tetrahedralize_surface,
    tube_mesh,
    validate_surface,
)

__all__ = ["ModalModel", "closest_points_on_triangles"]

log = logging.getLogger(__name__)

DEFAULT_MAX_FREQUENCY_HZ = 22050.0  # Nyquist of the 44.1 kHz audio chain


def closest_points_on_triangles(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Closest point to each p on triangle (a, b, c), all arrays (n, 3) (Ericson, RTCD 5.1.5)."""
    ab, ac, ap = b - a, c - a, p - a
    bp, cp = p - b, p - c

    def dot(u, v):
        return np.einsum("ij,ij->i", u, v)

    d1, d2 = dot(ab, ap), dot(ac, ap)
    d3, d4 = dot(ab, bp), dot(ac, bp)
    d5, d6 = dot(ab, cp), dot(ac, cp)
    vc = d1 * d4 - d3 * d2
    vb = d5 * d2 - d1 * d6
    va = d3 * d6 - d5 * d4

    def div(x, y):
        return x / np.where(y == 0, 1.0, y)

    v_ab = div(d1, d1 - d3)[:, None]
    w_ac = div(d2, d2 - d6)[:, None]
    w_bc = div(d4 - d3, (d4 - d3) + (d5 - d6))[:, None]
    denom = va + vb + vc
    v_in, w_in = div(vb, denom)[:, None], div(vc, denom)[:, None]
    conditions = [
        (d1 <= 0) & (d2 <= 0),
        (d3 >= 0) & (d4 <= d3),
        (vc <= 0) & (d1 >= 0) & (d3 <= 0),
        (d6 >= 0) & (d5 <= d6),
        (vb <= 0) & (d2 >= 0) & (d6 <= 0),
        (va <= 0) & ((d4 - d3) >= 0) & ((d5 - d6) >= 0),
    ]
    choices = [a, b, a + v_ab * ab, c, a + w_ac * ac, b + w_bc * (c - b)]
    out = a + v_in * ab + w_in * ac
    for cond, choice in zip(reversed(conditions), reversed(choices)):
        out = np.where(cond[:, None], choice, out)
    return out


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
        if r and (np.any(np.diff(self.frequencies_hz) < 0) or self.frequencies_hz[0] <= 0):
            raise ValueError("frequencies_hz must be positive and ascending")
        self.metadata = dict(metadata or {})
        self.metadata.setdefault("material", self.material.name)
        self.metadata.setdefault("element", self.element)
        self._surface = None
        self._tet_tree = None
        self._tinv = None

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

    @property
    def mass_kg(self) -> float:
        """Total mass [kg] (density times the meshed volume)."""
        return float(self.material.density_kg_m3 * tet_volumes(self.nodes_m, self.elements).sum())

    def describe(self) -> str:
        """One-line human description."""
        dims = ", ".join(f"{k}={v * 1000:.4g} mm" for k, v in self.dimensions_m.items())
        f = self.frequencies_hz
        band = f"{f[0]:.0f}-{f[-1]:.0f} Hz" if len(f) else "no modes"
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

    def _surface_data(self):
        if self._surface is None:
            from scipy.spatial import cKDTree

            faces, owner = boundary_faces(self.elements[:, :4])
            tri = self.nodes_m[faces]
            centre = tri.mean(axis=1)
            normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
            normal /= np.linalg.norm(normal, axis=1, keepdims=True)
            radius = float(np.linalg.norm(tri - centre[:, None], axis=2).max())
            self._surface = dict(faces=faces, owner=owner, tri=tri, normal=normal, radius=radius,
                                 tree=cKDTree(centre))
        return self._surface

    def _closest_surface(self, points: np.ndarray):
        """Closest surface point, face index and distance for each point."""
        s = self._surface_data()
        n_faces = len(s["faces"])
        k = min(16, n_faces)
        dc, cand = s["tree"].query(points, k=k)
        dc, cand = dc.reshape(len(points), k), cand.reshape(len(points), k)
        tri = s["tri"][cand]  # (n, k, 3, 3)
        p = np.repeat(points, k, axis=0)
        q = closest_points_on_triangles(p, tri[:, :, 0].reshape(-1, 3), tri[:, :, 1].reshape(-1, 3),
                                        tri[:, :, 2].reshape(-1, 3)).reshape(len(points), k, 3)
        d = np.linalg.norm(q - points[:, None], axis=2)
        best = np.argmin(d, axis=1)
        rows = np.arange(len(points))
        face, dist, closest = cand[rows, best], d[rows, best], q[rows, best]
        # Exact: a face not among the k nearest centroids is farther than dc_k - radius.
        unsure = np.flatnonzero((k < n_faces) & (dc[:, -1] - s["radius"] < dist))
        for i in unsure:  # rare (very uneven triangles): check every face
            allq = closest_points_on_triangles(np.repeat(points[i:i + 1], n_faces, axis=0),
                                               s["tri"][:, 0], s["tri"][:, 1], s["tri"][:, 2])
            dd = np.linalg.norm(allq - points[i], axis=1)
            j = int(np.argmin(dd))
            face[i], dist[i], closest[i] = j, dd[j], allq[j]
        return closest, face, dist

    def _barycentric(self, tet_idx: np.ndarray, points: np.ndarray) -> np.ndarray:
        if self._tinv is None:
            c = self.nodes_m[self.elements[:, :4]]
            self._tinv = np.linalg.inv(np.stack([c[:, 1] - c[:, 0], c[:, 2] - c[:, 0], c[:, 3] - c[:, 0]], axis=2))
        x0 = self.nodes_m[self.elements[tet_idx, 0]]
        lam = np.einsum("...ij,...j->...i", self._tinv[tet_idx], points - x0)
        return np.concatenate([1.0 - lam.sum(axis=-1, keepdims=True), lam], axis=-1)

    def _locate(self, points: np.ndarray):
        """Containing tet and barycentric coordinates; outside points go to the nearest surface point."""
        from scipy.spatial import cKDTree

        if self._tet_tree is None:
            self._tet_tree = cKDTree(self.nodes_m[self.elements[:, :4]].mean(axis=1))
        k = min(16, len(self.elements))
        _, cand = self._tet_tree.query(points, k=k)
        cand = cand.reshape(len(points), k)
        bary = self._barycentric(cand, np.repeat(points[:, None], k, axis=1))  # (n, k, 4)
        score = bary.min(axis=2)
        best = np.argmax(score, axis=1)
        rows = np.arange(len(points))
        tet = cand[rows, best]
        bary = bary[rows, best]
        outside = score[rows, best] < -1e-9
        if np.any(outside):
            q, face, _ = self._closest_surface(points[outside])
            t = self._surface_data()["owner"][face]
            b = np.clip(self._barycentric(t, q), 0.0, None)
            tet[outside] = t
            bary[outside] = b / b.sum(axis=1, keepdims=True)
        return tet, bary

    @staticmethod
    def _points(points_m) -> np.ndarray:
        p = np.atleast_2d(np.asarray(points_m, dtype=np.float64))
        if p.ndim != 2 or p.shape[1] != 3:
            raise ValueError(f"points_m must have shape (n, 3) or (3,), got {np.shape(points_m)}")
        if not np.all(np.isfinite(p)):
            raise ValueError("points_m contains non-finite values")
        return p

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
        tet, bary = self._locate(p)
        N = shape_functions(bary, self.element)  # (n, n_el)
        return np.einsum("pa,paxr->pxr", N, self.mode_shapes[self.elements[tet]])

    def surface_distance_m(self, points_m) -> np.ndarray:
        """Unsigned distance [m] from each point to the (faceted) surface of the mesh, (n,)."""
        p = self._points(points_m)
        return self._closest_surface(p)[2]

    def surface_normal_at(self, points_m) -> np.ndarray:
        """Outward unit surface normal at the surface point nearest to each point, (n, 3).

        Faceted for general meshes; exact (radial) on the curved faces of tubes and rods,
        whose facets are only a polygonal approximation of the cylinder.
        """
        p = self._points(points_m)
        _, face, _ = self._closest_surface(p)
        n = self._surface_data()["normal"][face].copy()
        if self.kind in ("tube", "rod"):
            radial = np.zeros_like(p)
            radial[:, 1:] = p[:, 1:]
            r = np.linalg.norm(radial, axis=1)
            curved = (np.abs(n[:, 0]) < 0.5) & (r > 0)
            sign = np.sign(np.einsum("ij,ij->i", n, radial))
            n[curved] = (radial[curved] / r[curved, None]) * sign[curved, None]
        return n

    def with_material(self, material, **options) -> "ModalModel":
        """This object in another material.

        With the same Poisson ratio, K scales with E and M with the density, so the modes are
        exact without a new solve: frequencies times sqrt((E'/rho') / (E/rho)), mass-normalized
        shapes times sqrt(rho / rho'); the band limit in the metadata scales with the
        frequencies. A different Poisson ratio changes the mode shapes: bars, tubes and rods
        are rebuilt with the stored options (``options`` override them); other meshes raise.
        """
        material = get_material(material)
        if math.isclose(material.poisson_ratio, self.material.poisson_ratio, rel_tol=0, abs_tol=1e-12):
            freq_scale, shape_scale = material_scaling(self.material, material)
            meta = dict(self.metadata, material=material.name, cache_hit=False)
            if "max_frequency_hz" in meta:
                meta["max_frequency_hz"] = float(meta["max_frequency_hz"]) * freq_scale
            return ModalModel(self.nodes_m, self.elements, self.frequencies_hz * freq_scale,
                              self.mode_shapes * shape_scale, material, element=self.element, metadata=meta)
        builders = {"bar": ModalModel.bar, "tube": ModalModel.tube, "rod": ModalModel.rod}
        if self.kind not in builders:
            raise ValueError("a different Poisson ratio needs a new solve; rebuild the model with from_mesh")
        opts = {k: self.metadata[k] for k in _RESULT_OPTIONS if k in self.metadata}
        opts.update(options)
        return builders[self.kind](**self.dimensions_m, material=material, **opts)

    def damping_matrix(self, contacts):
        """Modal damping matrix (r, r) for the given contacts (see :mod:`sensors.damping`)."""
        return modal_damping_matrix(self, contacts)

    # ------------------------------------------------------------------ persistence

    def _arrays(self) -> dict:
        return {
            "nodes_m": self.nodes_m,
            "elements": self.elements,
            "frequencies_hz": self.frequencies_hz,
            "mode_shapes": self.mode_shapes,
            "element": np.array(self.element),
            "material": np.array(json.dumps(self.material.to_dict())),
            "metadata": np.array(json.dumps(self.metadata, default=repr)),
        }

    @classmethod
    def _from_arrays(cls, data: dict) -> "ModalModel":
        return cls(data["nodes_m"], data["elements"], data["frequencies_hz"], data["mode_shapes"],
                   Material.from_dict(json.loads(str(data["material"]))), element=str(data["element"]),
                   metadata=json.loads(str(data["metadata"])))

    def save(self, path) -> Path:
        """Write the model to an ``.npz`` file (no pickle, atomically); returns the path."""
        path = Path(path)
        with atomic_open(path) as f:
            np.savez(f, **self._arrays())
        return path

    @classmethod
    def load(cls, path) -> "ModalModel":
        """Read a model written by :meth:`save`."""
        with np.load(Path(path), allow_pickle=False) as data:
            return cls._from_arrays({k: data[k] for k in data.files})

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
    def from_mesh(cls, mesh, material, **options) -> "ModalModel":
        """Any watertight ``trimesh.Trimesh`` (metres), tetrahedralized with pytetwild.

        The mesh is used in its own frame. Options as :meth:`bar`; ``element_size_m``
        defaults to a quarter of the smallest bounding-box extent.
        """
        opts = _options(options)
        material = get_material(material)
        surface = validate_surface(mesh)
        v = np.asarray(surface.vertices, dtype=np.float64)
        f = np.asarray(surface.faces, dtype=np.int64)
        key = cache_mod.content_key("modal-mesh", v, f, material.to_dict(), _key_options(opts))

        def make():
            return tetrahedralize_surface(surface, element_size_m=opts["element_size_m"],
                                          resolution=opts["resolution"], cache=opts["cache"],
                                          cache_dir=opts["cache_dir"])

        extents = np.ptp(v, axis=0)
        meta = {"kind": "mesh", "dimensions_m": {"extent_x_m": float(extents[0]), "extent_y_m": float(extents[1]),
                                                 "extent_z_m": float(extents[2])}}
        return cls._build(key, make, material, opts, meta)

    @classmethod
    def from_tet_mesh(cls, tet_mesh: TetMesh, material, **options) -> "ModalModel":
        """Build from an existing linear :class:`~sensors.meshing.TetMesh`.

        Options:
            element: "p2" (default, quadratic tets) or "p1" (linear; locks in bending).
            max_frequency_hz: Band limit [Hz], default 22050 (Nyquist of 44.1 kHz).
            resolution: Multiplies the number of elements in each direction (default 1).
            element_size_m: Target element size [m] (overrides the shape's default).
            cache: Use the on-disk cache (default True).
            cache_dir: Cache directory (default $AAS_GYM_CACHE or ~/.cache/aas_gym).
            progress: None (a progress bar appears if the build takes over a second),
                True (always) or False (never).
        """
        opts = _options(options)
        material = get_material(material)
        key = cache_mod.content_key("modal-tets", tet_mesh.digest(), material.to_dict(), _key_options(opts))
        meta = {"kind": tet_mesh.kind, "dimensions_m": dict(tet_mesh.dimensions_m)}
        return cls._build(key, lambda: tet_mesh, material, opts, meta)

    @classmethod
    def _build_structured(cls, kind, mesher, dims, material, options) -> "ModalModel":
        opts = _options(options)
        material = get_material(material)
        # The key needs no meshing: a cached build is just a file read.
        key = cache_mod.content_key("modal-" + kind, dims, material.to_dict(), _key_options(opts))

        def make():
            return mesher(**dims, element_size_m=opts["element_size_m"], resolution=opts["resolution"])

        return cls._build(key, make, material, opts, {"kind": kind, "dimensions_m": {k: float(v) for k, v in dims.items()}})

    @classmethod
    def _cached(cls, key, opts) -> "ModalModel | None":
        hit = cache_mod.load_arrays(key, opts["cache_dir"])
        if hit is None:
            return None
        try:
            model = cls._from_arrays(hit)
        except (KeyError, ValueError) as exc:
            log.warning("ignoring cache entry %s: %s", key[:12], exc)
            return None
        model.metadata["cache_hit"] = True
        return model

    @classmethod
    def _build(cls, key, make_mesh, material, opts, meta) -> "ModalModel":
        if not opts["cache"]:
            return cls._solve(key, make_mesh, material, opts, meta)
        model = cls._cached(key, opts)
        if model is not None:
            return model
        with cache_mod.build_lock(key, opts["cache_dir"]):
            # Another process may have built it while this one waited for the lock.
            model = cls._cached(key, opts)
            return model if model is not None else cls._solve(key, make_mesh, material, opts, meta)

    @classmethod
    def _solve(cls, key, make_mesh, material, opts, meta) -> "ModalModel":
        from tqdm.auto import tqdm

        stages = ["mesh", "elements", "assemble", "eigensolve"]
        bar = tqdm(total=len(stages), desc=f"modal {meta['kind']}", unit="stage",
                   disable=opts["progress"] is False, delay=0.0 if opts["progress"] else 1.0, leave=False)
        t0 = time.perf_counter()
        timings = {}
        try:
            def stage(name):
                bar.set_postfix_str(name, refresh=False)
                timings[name] = time.perf_counter()

            stage("mesh")
            tm = make_mesh()
            check_tet_quality(tm.vertices_m, tm.tets)
            bar.update()
            stage("elements")
            if opts["element"] == "p2":
                nodes, elements = quadratic_mesh(tm)
            else:
                nodes, elements = tm.vertices_m, tm.tets
            bar.update()
            stage("assemble")
            K, M = assemble(nodes, elements, material, opts["element"])
            bar.update()
            stage("eigensolve")
            lam, U = solve_modes(K, M, nodes, opts["max_frequency_hz"], progress=lambda s: bar.set_postfix_str(s, refresh=False))
            bar.update()
        finally:
            bar.close()
        end = time.perf_counter()
        names = list(timings)
        stage_s = {n: (timings[names[i + 1]] if i + 1 < len(names) else end) - timings[n] for i, n in enumerate(names)}
        meta = dict(meta)
        meta.update(_key_options(opts), n_dof=int(K.shape[0]), n_tets=int(len(elements)), build_time_s=end - t0,
                    stage_times_s=stage_s, cache_key=key, code_version=cache_mod.CODE_VERSION)
        r = U.shape[1]
        model = cls(nodes, elements, np.sqrt(lam) / (2.0 * np.pi), U.reshape(len(nodes), 3, r), material,
                    element=opts["element"], metadata=meta)
        log.info("built %s in %.2f s", model.describe(), end - t0)
        if opts["cache"]:
            cache_mod.save_arrays(key, model._arrays(), opts["cache_dir"])
        return model


_DEFAULTS = dict(element="p2", max_frequency_hz=DEFAULT_MAX_FREQUENCY_HZ, resolution=1.0, element_size_m=None,
                 cache=True, cache_dir=None, progress=None)


def _options(options: dict) -> dict:
    unknown = set(options) - set(_DEFAULTS)
    if unknown:
        raise TypeError(f"unknown option(s) {sorted(unknown)}; valid: {sorted(_DEFAULTS)}")
    opts = {**_DEFAULTS, **options}
    opts["element"] = str(opts["element"]).lower()
    if opts["element"] not in ("p1", "p2"):
        raise ValueError(f"element must be 'p1' or 'p2', got {options.get('element')!r}")
    f = opts["max_frequency_hz"]
    if not (isinstance(f, (int, float, np.floating, np.integer)) and math.isfinite(f) and f > 0):
        raise ValueError(f"max_frequency_hz must be a positive number, got {f!r}")
    opts["max_frequency_hz"] = float(f)
    return opts


#: The options the modes depend on: part of the cache key, kept in the metadata for rebuilds.
_RESULT_OPTIONS = ("element", "max_frequency_hz", "resolution", "element_size_m")


def _key_options(opts: dict) -> dict:
    return {k: opts[k] for k in _RESULT_OPTIONS}
