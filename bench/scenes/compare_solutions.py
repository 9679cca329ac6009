#!/usr/bin/python3
"""Compares sirad solutions of one mesh patch by patch and room by room.

    bench/scenes/compare_solutions.py REFERENCE.ply CANDIDATE.ply [CANDIDATE.ply ...] [--rooms apartment]
    bench/scenes/compare_solutions.py --surfaces apartment SOLUTION.ply [SOLUTION.ply ...]
    bench/scenes/compare_solutions.py --planes A.ply B.ply

Both are sirad's own binary PLY of the same scene and --patches (one face per patch, in the same
order). Prints, per candidate, the relative RMS error per patch over the patches that do not emit
(area-weighted, all three channels: sqrt(sum A |B - B_ref|^2 / sum A |B_ref|^2), the measure of
solver/metrics.h) and, with --rooms apartment, each room's mean radiosity over the reference's
(the patches whose centre, moved 1 cm along the face's normal, lies in the room: walls count for
the room they face). The rooms are those of tests/data/blender/make_apartment.py (`apartment`) or make_studio.py
(`studio`).
With --surfaces, each solution alone (any meshing): per room, the area-weighted mean radiosity
(r + g + b) of its floor (faces up within 1 cm of y = 0) and of its walls (vertical faces),
what the camera sees of a room, leaving out the ceiling, whose part over a lamp lies in the gap.
With --planes, two solutions of one scene meshed alike or not (a glb and an OBJ export): per plane
(patches grouped by normal to 1e-3 and offset to 1 mm, facing apart kept apart), the area-weighted
mean radiosity of each; prints the area-weighted mean and the largest relative difference over the
planes of at least 0.05 m^2 in both that the light reaches (above 1e-3 of the mean radiosity),
each difference over the larger of the two means.
"""
import sys

import numpy as np

# The rooms of the corpus scenes (tests/data/blender/make_*.py) in Blender's frame before the
# building's turn: x range, y range, 0 < z < height; `turn` (degrees about z) and `offset` place
# the building (glTF's frame: Blender's x, z, -y).
ROOMS = {
    "apartment": {"turn": 0.0, "offset": (0.0, 0.0), "height": 2.6,
                  "rooms": {"living": (0, 5, 0, 4), "hall": (0, 5, 4, 6), "bedroom": (5, 8, 0, 3.5), "bath": (5, 8, 3.5, 6)}},
    "studio": {"turn": 30.0, "offset": (1.0, -0.5), "height": 2.7,
               "rooms": {"west": (0, 4.45, 0, 4), "east": (4.55, 6, 0, 2.45), "closet": (4.55, 6, 2.55, 4)}},
}


def read_ply(path):
    with open(path, "rb") as f:
        data = f.read()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode("ascii").splitlines()
    vertices = faces = 0
    vprops, fprops, element = [], [], None
    for line in header:
        w = line.split()
        if w[0] == "element":
            element = w[1]
            if element == "vertex":
                vertices = int(w[2])
            elif element == "face":
                faces = int(w[2])
        elif w[0] == "property":
            (vprops if element == "vertex" else fprops).append(w[1:])
    sizes = {"float": 4, "uchar": 1, "int": 4}
    vtype = np.dtype([(p[-1], {"float": "<f4", "uchar": "u1", "int": "<i4"}[p[0]]) for p in vprops])
    verts = np.frombuffer(data, vtype, vertices, end)
    pos = np.stack([verts["x"], verts["y"], verts["z"]], 1).astype(np.float64)
    off = end + vertices * vtype.itemsize
    assert fprops[0][:3] == ["list", "uchar", "int"], fprops[0]
    rest = [(p[-1], {"float": "<f4", "uchar": "u1", "int": "<i4"}[p[0]]) for p in fprops[1:]]
    ftype = np.dtype([("n", "u1"), ("v", "<i4", 3)] + rest)
    fa = np.frombuffer(data, ftype, faces, off)
    assert (fa["n"] == 3).all()
    tri = pos[fa["v"]]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area = 0.5 * np.linalg.norm(cross, axis=1)
    normal = cross / np.maximum(2 * area, 1e-30)[:, None]
    b = np.stack([fa["radiosity_r"], fa["radiosity_g"], fa["radiosity_b"]], 1).astype(np.float64)
    e = np.stack([fa["emission_r"], fa["emission_g"], fa["emission_b"]], 1).astype(np.float64)
    return dict(area=area, centre=tri.mean(1), normal=normal, b=b, emits=(e > 0).any(1))


def in_rooms(c, plan):
    """Per room of `plan` (an entry of ROOMS), which patches of solution `c` it holds: their
    centre, moved 1 cm along the face's normal (a wall counts for the room it faces), inside the
    room's box."""
    p = c["centre"] + 0.01 * c["normal"]
    t = np.radians(plan["turn"])
    xs, ys = p[:, 0] - plan["offset"][0], -p[:, 2] - plan["offset"][1]
    x, y, z = xs * np.cos(t) + ys * np.sin(t), -xs * np.sin(t) + ys * np.cos(t), p[:, 1]
    return {name: (x > x0) & (x < x1) & (y > y0) & (y < y1) & (z > 0) & (z < plan["height"])
            for name, (x0, x1, y0, y1) in plan["rooms"].items()}


def surfaces(rooms, paths):
    for path in paths:
        c = read_ply(path)
        keep = ~c["emits"]
        line = f"{path} ({len(c['area'])} patches):"
        for name, room in in_rooms(c, rooms).items():
            m = keep & room
            for part, sel in (("floor", (c["normal"][:, 1] > 0.999) & (c["centre"][:, 1] < 0.01)),
                              ("walls", np.abs(c["normal"][:, 1]) < 1e-3)):
                w = c["area"][m & sel]
                line += f" {name}-{part} {(w * c['b'][m & sel].sum(1)).sum() / w.sum():.4f}"
        print(line)


def planes(a_path, b_path):
    def per_plane(path):
        c = read_ply(path)
        keep = ~c["emits"]
        out = {}
        for j in np.nonzero(keep)[0]:
            n = c["normal"][j]
            key = (*np.round(n, 3), round(float(np.dot(n, c["centre"][j])), 3))
            a, b = out.get(key, (0.0, 0.0))
            out[key] = (a + c["area"][j], b + c["area"][j] * c["b"][j].sum())
        return out
    pa, pb = per_plane(a_path), per_plane(b_path)
    # Planes that the whole scene's light hardly reaches (below 1e-3 of the mean radiosity: the
    # outer faces that face nothing) are left out: there a relative difference is noise over 0.
    floor = 1e-3 * sum(b for _, b in pa.values()) / sum(a for a, _ in pa.values())
    total, weighted, worst, worst_key = 0.0, 0.0, 0.0, None
    for key, (aa, ba) in pa.items():
        if key not in pb or aa < 0.05 or pb[key][0] < 0.05:
            continue
        ma, mb = ba / aa, pb[key][1] / pb[key][0]
        if max(ma, mb) <= floor:
            continue
        d = abs(mb - ma) / max(ma, mb)  # at most 1: a plane black in one and lit in the other
        total += aa
        weighted += aa * d
        if d > worst:
            worst, worst_key = d, key
    print(f"{a_path} vs {b_path}: {len(pa)} / {len(pb)} planes, mean relative difference {100 * weighted / total:.2f} % "
          f"(area {total:.1f} m^2), largest {100 * worst:.2f} % (plane {worst_key})")


def main(argv):
    if argv and argv[0] == "--planes":
        planes(argv[1], argv[2])
        return
    if argv and argv[0] == "--surfaces":
        surfaces(ROOMS[argv[1]], argv[2:])
        return
    rooms = None
    if "--rooms" in argv:
        i = argv.index("--rooms")
        rooms = ROOMS[argv[i + 1]]
        argv = argv[:i] + argv[i + 2:]
    ref = read_ply(argv[0])
    keep = ~ref["emits"]
    a = ref["area"][keep]
    denom = (a * (ref["b"][keep] ** 2).sum(1)).sum()
    for path in argv[1:]:
        c = read_ply(path)
        assert len(c["area"]) == len(ref["area"]), "different meshes"
        err = np.sqrt((a * ((c["b"][keep] - ref["b"][keep]) ** 2).sum(1)).sum() / denom)
        line = f"{path}: relative RMS per patch {100 * err:.2f} %"
        if rooms:
            for name, room in in_rooms(ref, rooms).items():
                m = keep & room
                w = ref["area"][m]
                ratio = (w * c["b"][m].sum(1)).sum() / (w * ref["b"][m].sum(1)).sum()
                line += f", {name} {ratio:.4f}"
        print(line)


if __name__ == "__main__":
    main(sys.argv[1:])
