"""How faithful CoACD's convex pieces are to the solid, per CoACD setting (issue 30).

For each everyday object and setting: CoACD's CPU time, the piece count, and three measures of the
union U of the pieces against the solid S (exact booleans by manifold3d):
extra volume vol(U - S) / vol(S) (what the pieces fill that is not solid: cavities, chords of thin
walls), missed volume vol(S - U) / vol(S), and the one-sided Hausdorff distance from U's surface to
S (vertices plus 4000 area-weighted samples of U's surface; how far a contact can sit off the
solid). The pieces of S cover S when the missed volume is ~0.

    OMP_NUM_THREADS=1 python benchmarks/collision_fidelity.py can mug bottle --settings current mcts_it10
"""
import argparse
import time

import coacd
import manifold3d as m3
import numpy as np
import trimesh

from aas_gym import collision
from sensors.objects import get_object

#: name -> (CoACD options, simplification tolerance as a fraction of the bounding-box diagonal)
SETTINGS = {
    "current": (dict(collision.COACD_OPTIONS), collision.SIMPLIFY_TOLERANCE),
    "mcts_it10": ({**collision.COACD_OPTIONS, "mcts_iterations": 10}, collision.SIMPLIFY_TOLERANCE),
    "depth1": ({**collision.COACD_OPTIONS, "mcts_max_depth": 1}, collision.SIMPLIFY_TOLERANCE),
    "simplify_2e-3": (dict(collision.COACD_OPTIONS), 2e-3),
}


def pieces(surface: trimesh.Trimesh, options: dict, tolerance: float):
    """(convex hulls, CoACD CPU time [s], faces given to CoACD), as collision.convex_decomposition."""
    v, f = np.asarray(surface.vertices, float), np.asarray(surface.faces, np.int64)
    t0 = time.process_time()
    if len(f) > collision.SIMPLIFY_ABOVE_FACES:
        v, f = collision.simplified(v, f, tolerance * float(np.linalg.norm(v.max(0) - v.min(0))))
    coacd.set_log_level("error")
    parts = coacd.run_coacd(coacd.Mesh(v, f), **options)
    hulls = [trimesh.Trimesh(np.asarray(a, float), np.asarray(b), process=True).convex_hull for a, b in parts]
    return hulls, time.process_time() - t0, len(f)


def fidelity(surface: trimesh.Trimesh, hulls) -> tuple[float, float, float]:
    """(extra volume fraction, missed volume fraction, Hausdorff of the union to the solid [m])."""
    solid = m3.Manifold(m3.Mesh(vert_properties=np.asarray(surface.vertices, np.float32),
                                tri_verts=np.asarray(surface.faces, np.uint32)))
    union = m3.Manifold()
    for h in hulls:
        union = union + m3.Manifold.hull_points(np.asarray(h.vertices, np.float32))
    volume = solid.volume()
    out = union.to_mesh()
    skin = trimesh.Trimesh(np.asarray(out.vert_properties[:, :3], float), np.asarray(out.tri_verts), process=False)
    points = np.concatenate([skin.vertices, trimesh.sample.sample_surface(skin, 4000, seed=1)[0]])
    signed = np.concatenate([trimesh.proximity.signed_distance(surface, points[k:k + 2000])
                             for k in range(0, len(points), 2000)])  # positive inside the solid
    return (union - solid).volume() / volume, (solid - union).volume() / volume, max(0.0, float(-signed.min()))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("objects", nargs="+")
    ap.add_argument("--settings", nargs="+", default=list(SETTINGS), choices=list(SETTINGS))
    args = ap.parse_args(argv)
    print("| object | setting | faces | pieces | CoACD CPU s | extra volume % | missed volume % | Hausdorff mm |")
    print("|---|---|---:|---:|---:|---:|---:|---:|")
    for name in args.objects:
        surface = get_object(name).solid().surface
        for setting in args.settings:
            hulls, cpu_s, n_faces = pieces(surface, *SETTINGS[setting])
            extra, missed, hausdorff_m = fidelity(surface, hulls)
            print(f"| {name} | {setting} | {n_faces} | {len(hulls)} | {cpu_s:.2f} | {100 * extra:.2f} | "
                  f"{100 * missed:.2f} | {1e3 * hausdorff_m:.2f} |", flush=True)


if __name__ == "__main__":
    main()
