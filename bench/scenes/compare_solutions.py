#!/usr/bin/python3
"""Compares sirad solutions of one mesh patch by patch and room by room.

    bench/scenes/compare_solutions.py REFERENCE.ply CANDIDATE.ply [CANDIDATE.ply ...] [--rooms apartment]
    bench/scenes/compare_solutions.py --surfaces apartment SOLUTION.ply [SOLUTION.ply ...]

Both are sirad's own binary PLY of the same scene and --patches (one face per patch, in the same
order). Prints, per candidate, the relative RMS error per patch over the patches that do not emit
(area-weighted, all three channels: sqrt(sum A |B - B_ref|^2 / sum A |B_ref|^2), the measure of
core/metrics.h) and, with --rooms apartment, each room's mean radiosity over the reference's
(the patches whose centre, moved 1 cm along the face's normal, lies in the room: walls count for
the room they face). The rooms are those of bench/scenes/make_apartment.py in glTF's Y-up frame.
With --surfaces, each solution alone (any meshing): per room, the area-weighted mean radiosity
(r + g + b) of its floor (faces up within 1 cm of y = 0) and of its walls (vertical faces),
what the camera sees of a room, leaving out the ceiling, whose part over a lamp lies in the gap.
"""
import sys

import numpy as np

ROOMS = {  # x range, z range (glTF: Blender's y is -z), y (height) 0..2.6
    "apartment": {"living": (0, 5, -4, 0), "hall": (0, 5, -6, -4), "bedroom": (5, 8, -3.5, 0), "bath": (5, 8, -6, -3.5)},
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


def surfaces(rooms, paths):
    for path in paths:
        c = read_ply(path)
        p = c["centre"] + 0.01 * c["normal"]
        keep = ~c["emits"]
        line = f"{path} ({len(c['area'])} patches):"
        for name, (x0, x1, z0, z1) in rooms.items():
            m = keep & (p[:, 0] > x0) & (p[:, 0] < x1) & (p[:, 2] > z0) & (p[:, 2] < z1) & (p[:, 1] > 0) & (p[:, 1] < 2.6)
            for part, sel in (("floor", (c["normal"][:, 1] > 0.999) & (c["centre"][:, 1] < 0.01)),
                              ("walls", np.abs(c["normal"][:, 1]) < 1e-3)):
                w = c["area"][m & sel]
                line += f" {name}-{part} {(w * c['b'][m & sel].sum(1)).sum() / w.sum():.4f}"
        print(line)


def main(argv):
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
            p = ref["centre"] + 0.01 * ref["normal"]
            for name, (x0, x1, z0, z1) in rooms.items():
                m = keep & (p[:, 0] > x0) & (p[:, 0] < x1) & (p[:, 2] > z0) & (p[:, 2] < z1) & (p[:, 1] > 0) & (p[:, 1] < 2.6)
                w = ref["area"][m]
                ratio = (w * c["b"][m].sum(1)).sum() / (w * ref["b"][m].sum(1)).sum()
                line += f", {name} {ratio:.4f}"
        print(line)


if __name__ == "__main__":
    main(sys.argv[1:])
