"""How a ModalModel is built: options, the content-addressed disk cache with a build lock, and
the pipeline tet mesh -> P2 (or P1) elements -> K, M -> elastic modes up to the band limit.

The functions take the model class as ``cls`` so that this module does not import
``modal_model`` (which imports this one)."""

from __future__ import annotations

import logging
import math
import time

import numpy as np

from .._infra import cache as cache_mod
from . import io as modal_io
from ..fem.eigen import solve_modes
from ..fem import mirror
from ..fem.assembly import assemble_blocks, assembled_csr
from ..fem.direct_solver import preload_in_background
from ..mesh.quadratic import quadratic_mesh
from ..mesh.tets import DEFAULT_MAX_DOF, check_tet_quality

log = logging.getLogger(__name__)

DEFAULT_MAX_FREQUENCY_HZ = 22050.0  # Nyquist of the 44.1 kHz audio chain


def cached(cls, key, opts):
    """The model stored under ``key`` in the disk cache, or None."""
    hit = cache_mod.load_arrays(key, opts["cache_dir"])
    if hit is None:
        return None
    try:
        model = modal_io.from_arrays(cls, hit)
    except (KeyError, ValueError) as exc:
        log.warning("ignoring cache entry %s: %s", key[:12], exc)
        return None
    model.metadata["cache_hit"] = True
    return model

def build(cls, key, make_mesh, material, opts: dict, meta: dict):
    """The model behind cache ``key``: read from the disk cache, or built by ``make_mesh`` and
    solved once (other processes wait on a lock instead of solving it again)."""
    if not opts["cache"]:
        return _solve(cls, key, make_mesh, material, opts, meta)
    model = cached(cls, key, opts)
    if model is not None:
        return model
    with cache_mod.build_lock(key, opts["cache_dir"]):
        # Another process may have built it while this one waited for the lock.
        model = cached(cls, key, opts)
        return model if model is not None else _solve(cls, key, make_mesh, material, opts, meta)

def _solve(cls, key, make_mesh, material, opts, meta):
    """Mesh, elements, K and M, eigensolve, with a progress bar past a second."""
    from tqdm.auto import tqdm  # ~0.05 s to import: only a build shows a bar

    preload_in_background()  # MKL loads while the mesh is made and assembled

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
        # A mesh built mirror-symmetric is solved per symmetry class, the classes side by side.
        split = mirror.mirror_split(nodes, elements, tm.mirror_axes) if tm.mirror_axes else None
        if split is None:
            blocks = assemble_blocks(nodes, elements, material, opts["element"], analyze=True)
            K, M = assembled_csr(blocks)
        else:
            classes = split.assemble(nodes, material, opts["element"])
        bar.update()
        stage("eigensolve")
        solved = {}
        if split is None:
            lam, U = solve_modes(K, M, nodes, opts["max_frequency_hz"], info=solved,
                                 progress=lambda s: bar.set_postfix_str(s, refresh=False),
                                 factorize_shifted=blocks.factorize_shifted,  # PARDISO takes the node blocks
                                 mass_product=blocks.mass_product)
        else:
            lam, U = mirror.solve_mirrored_modes(split, nodes, classes, opts["max_frequency_hz"], info=solved,
                                                 progress=lambda s: bar.set_postfix_str(s, refresh=False))
        bar.update()
    finally:
        bar.close()
    end = time.perf_counter()
    names = list(timings)
    stage_s = {n: (timings[names[i + 1]] if i + 1 < len(names) else end) - timings[n] for i, n in enumerate(names)}
    meta = dict(meta)
    meta.update(key_options(opts), n_dof=3 * len(nodes), n_tets=int(len(elements)), build_time_s=end - t0,
                stage_times_s=stage_s, cache_key=key, code_version=cache_mod.CODE_VERSION,
                solver=solved.get("solver"),
                eigensolve=dict(solved))  # the factorization's time, the Krylov solves (fem.eigen.solve_modes)
    r = U.shape[1]
    model = cls(nodes, elements, np.sqrt(lam) / (2.0 * np.pi), U.reshape(len(nodes), 3, r), material,
                element=opts["element"], metadata=meta)
    log.info("built %s in %.2f s", model.describe(), end - t0)
    if opts["cache"]:
        start = time.perf_counter()
        cache_mod.save_arrays(key, modal_io.to_arrays(model), opts["cache_dir"])
        model.metadata["write_s"] = time.perf_counter() - start  # this build's only (not in the entry)
    return model


_DEFAULTS = dict(element="p2", max_frequency_hz=DEFAULT_MAX_FREQUENCY_HZ, resolution=1.0, element_size_m=None,
                 cache=True, cache_dir=None, progress=None, max_dof=DEFAULT_MAX_DOF)


def options(options: dict) -> dict:
    """The build options with their defaults, checked."""
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
RESULT_OPTIONS = ("element", "max_frequency_hz", "resolution", "element_size_m")


def key_options(opts: dict) -> dict:
    return {k: opts[k] for k in RESULT_OPTIONS}
