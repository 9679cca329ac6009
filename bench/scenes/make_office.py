#!/usr/bin/python3
"""Writes scenes/open_office.obj and .mtl: an open-plan office of 24 x 12 x 3 m (metres, Y up)
with many objects, for the scale benchmarks (bench/scale_bench.cpp) and as a scene of many
small parts: 32 desks, 32 chairs, 8 partitions, 6 columns, 4 cabinets and 24 ceiling lamps, each
its own OBJ object (`o`), every box closed with outward faces; the room's faces point inwards.

    bench/scenes/make_office.py [OUT_DIR]   (default: scenes/ beside this repository's bench/)
"""
import os
import sys

out_dir = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "scenes")
verts, faces = [], []  # faces: (object, material, (i, j, k, l)) as quads, CCW from the front
objects = []


def vert(x, y, z):
    verts.append((x, y, z))
    return len(verts)


def quad(obj, mat, a, b, c, d):
    faces.append((obj, mat, (a, b, c, d)))


def box(name, mat, x0, y0, z0, x1, y1, z1, inward=False):
    """An axis-aligned box; faces outward (inward for the room)."""
    objects.append(name)
    o = len(objects) - 1
    p = [vert(x, y, z) for x in (x0, x1) for y in (y0, y1) for z in (z0, z1)]
    # p index: 4 * ix + 2 * iy + iz
    def v(ix, iy, iz):
        return p[4 * ix + 2 * iy + iz]
    sides = [  # outward CCW quads
        (v(0, 0, 0), v(0, 0, 1), v(0, 1, 1), v(0, 1, 0)),  # -x
        (v(1, 0, 0), v(1, 1, 0), v(1, 1, 1), v(1, 0, 1)),  # +x
        (v(0, 0, 0), v(1, 0, 0), v(1, 0, 1), v(0, 0, 1)),  # -y
        (v(0, 1, 0), v(0, 1, 1), v(1, 1, 1), v(1, 1, 0)),  # +y
        (v(0, 0, 0), v(0, 1, 0), v(1, 1, 0), v(1, 0, 0)),  # -z
        (v(0, 0, 1), v(1, 0, 1), v(1, 1, 1), v(0, 1, 1)),  # +z
    ]
    for s in sides:
        quad(o, mat, *(tuple(reversed(s)) if inward else s))


def panel(name, mat, x0, z0, x1, z1, y):
    """A horizontal emitter facing down (-y) at height y."""
    objects.append(name)
    o = len(objects) - 1
    a, b, c, d = vert(x0, y, z0), vert(x1, y, z0), vert(x1, y, z1), vert(x0, y, z1)
    quad(o, mat, a, b, c, d)  # normal (b - a) x (d - a) = x x z = -y: faces down


W, D, H = 24.0, 12.0, 3.0
box("room", "wall", 0, 0, 0, W, H, D, inward=True)
for r in range(4):
    for c in range(8):
        x, z = 1.5 + c * 2.8, 1.5 + r * 2.6
        box(f"desk_{r}_{c}", "desk", x, 0.72, z, x + 1.6, 0.76, z + 0.8)
        box(f"desk_leg_{r}_{c}", "metal", x + 0.7, 0.0, z + 0.3, x + 0.9, 0.72, z + 0.5)
        box(f"chair_{r}_{c}", "chair", x + 0.55, 0.0, z + 0.95, x + 1.05, 0.45, z + 1.45)
        box(f"chair_back_{r}_{c}", "chair", x + 0.55, 0.45, z + 1.4, x + 1.05, 1.0, z + 1.45)
for r in range(4):
    for c in range(2):
        x, z = 1.2 + c * 11.2, 2.4 + r * 2.6
        box(f"partition_{r}_{c}", "partition", x, 0.0, z, x + 11.0, 1.3, z + 0.05)
for c in range(6):
    x = 3.4 + c * 3.6
    box(f"column_{c}", "wall", x, 0.0, 11.0, x + 0.4, H, 11.4)
for c in range(4):
    box(f"cabinet_{c}", "desk", 0.2, 0.0, 1.0 + c * 2.5, 0.8, 1.2, 2.2 + c * 2.5)
for r in range(4):
    for c in range(6):
        x, z = 2.0 + c * 3.6, 1.5 + r * 2.6
        panel(f"lamp_{r}_{c}", "lamp", x, z, x + 1.2, z + 0.6, H - 0.01)

with open(os.path.join(out_dir, "open_office.mtl"), "w") as f:
    f.write("# sirad: open-plan office materials (Kd reflectance, Ke emitted radiance)\n")
    for name, kd, ke in (("wall", "0.75 0.74 0.7", None), ("desk", "0.55 0.4 0.25", None), ("metal", "0.5 0.5 0.52", None),
                         ("chair", "0.15 0.2 0.45", None), ("partition", "0.35 0.45 0.35", None),
                         ("lamp", "0.8 0.8 0.8", "12 11.5 10.5")):
        f.write(f"newmtl {name}\nKd {kd}\n" + (f"Ke {ke}\n" if ke else ""))
with open(os.path.join(out_dir, "open_office.obj"), "w") as f:
    f.write("# sirad: an open-plan office, 24 x 12 x 3 m, written by bench/scenes/make_office.py\n")
    f.write("# sirad camera eye 1 1.7 1 look 14 1.0 8 up 0 1 0 fov 70\n")
    f.write("mtllib open_office.mtl\n")
    for x, y, z in verts:
        f.write(f"v {x:g} {y:g} {z:g}\n")
    current = (None, None)
    for o, mat, q in faces:
        if current[0] != o:
            f.write(f"o {objects[o]}\n")
        if current[1] != mat or current[0] != o:
            f.write(f"usemtl {mat}\n")
        current = (o, mat)
        f.write("f {} {} {} {}\n".format(*q))
print(f"{len(objects)} objects, {len(faces)} quads")
