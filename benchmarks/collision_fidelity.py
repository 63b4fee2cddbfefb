"""How faithful CoACD's convex pieces are to the solid, per CoACD setting (issue 30).

For each everyday object and setting: CoACD's CPU time, the piece count, and three measures of the
union U of the pieces against the solid S (exact booleans by manifold3d):
extra volume vol(U - S) / vol(S) (what the pieces fill that is not solid: cavities, chords of thin
walls), missed volume vol(S - U) / vol(S), and the one-sided Hausdorff distance from U's surface to
S (vertices plus 4000 area-weighted samples of U's surface; how far a contact can sit off the
solid). The pieces of S cover S when the missed volume is ~0; the missed depth (the deepest vertex of
S - U below S's surface) tells a skin of rounding (microns) from a region a contact could sink into.

    OMP_NUM_THREADS=1 python benchmarks/collision_fidelity.py can mug bottle --settings current previous --out /tmp/fidelity.md
"""
import argparse
import time

import manifold3d as m3
import numpy as np
import trimesh

from aas_gym import collision
from sensors.objects import get_object

#: The settings before issue 30's sweep (threshold 5%, at most 32 pieces, 1000 samples, whole solid).
PREVIOUS = dict(collision.COACD_OPTIONS, threshold=0.05, max_convex_hull=32, resolution=1000)

#: name -> (CoACD options, simplification tolerance as a fraction of the bounding-box diagonal,
#: decompose a half or quarter at the solid's mirror planes)
SETTINGS = {
    "current": (dict(collision.COACD_OPTIONS), collision.SIMPLIFY_TOLERANCE, True),
    "current_whole": (dict(collision.COACD_OPTIONS), collision.SIMPLIFY_TOLERANCE, False),
    "previous": (PREVIOUS, collision.SIMPLIFY_TOLERANCE, False),
    "previous_mirrored": (PREVIOUS, collision.SIMPLIFY_TOLERANCE, True),
    "mirrored_resolution_1000": ({**PREVIOUS, "threshold": 0.03, "max_convex_hull": 48}, collision.SIMPLIFY_TOLERANCE, True),
    "mcts_it10": ({**PREVIOUS, "mcts_iterations": 10}, collision.SIMPLIFY_TOLERANCE, False),
    "depth1": ({**PREVIOUS, "mcts_max_depth": 1}, collision.SIMPLIFY_TOLERANCE, False),
    "simplify_2e-3": (PREVIOUS, 2e-3, False),
}


def pieces(surface: trimesh.Trimesh, options: dict, tolerance: float, symmetric: bool):
    """(convex hulls, CPU time of collision.decompose [s]): what convex_decomposition builds, uncached."""
    t0 = time.process_time()
    parts = collision.decompose(surface.vertices, surface.faces, options, tolerance, symmetric)
    cpu_s = time.process_time() - t0
    return [trimesh.Trimesh(p).convex_hull for p in parts], cpu_s


def depth_below(surface: trimesh.Trimesh, points: np.ndarray) -> float:
    """The deepest of ``points`` below the closed surface [m] (0 for none inside)."""
    signed = np.concatenate([trimesh.proximity.signed_distance(surface, points[k:k + 2000])
                             for k in range(0, len(points), 2000)])  # positive inside the solid
    return max(0.0, float(signed.max())) if len(signed) else 0.0


def fidelity(surface: trimesh.Trimesh, hulls) -> tuple[float, float, float, float]:
    """(extra volume fraction, missed volume fraction, Hausdorff of the union to the solid [m],
    missed depth [m])."""
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
    missed = (solid - union)
    missed_depth_m = depth_below(surface, np.asarray(missed.to_mesh().vert_properties[:, :3], float))
    return ((union - solid).volume() / volume, missed.volume() / volume, max(0.0, float(-signed.min())),
            missed_depth_m)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("objects", nargs="+")
    ap.add_argument("--settings", nargs="+", default=["current", "previous"], choices=list(SETTINGS))
    ap.add_argument("--out", help="also write the table to this Markdown file")
    args = ap.parse_args(argv)
    lines = ["| object | setting | pieces | CPU s | extra volume % | missed volume % | missed depth mm | Hausdorff mm |",
             "|---|---|---:|---:|---:|---:|---:|---:|"]
    print("\n".join(lines), flush=True)
    for name in args.objects:
        surface = get_object(name).solid().surface
        for setting in args.settings:
            hulls, cpu_s = pieces(surface, *SETTINGS[setting])
            extra, missed, hausdorff_m, depth_m = fidelity(surface, hulls)
            lines.append(f"| {name} | {setting} | {len(hulls)} | {cpu_s:.2f} | {100 * extra:.2f} | "
                         f"{100 * missed:.2f} | {1e3 * depth_m:.3f} | {1e3 * hausdorff_m:.2f} |")
            print(lines[-1], flush=True)
    if args.out:
        with open(args.out, "w") as out:
            out.write("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
