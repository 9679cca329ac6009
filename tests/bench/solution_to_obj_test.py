#!/usr/bin/python3
"""bench/cycles/solution_to_obj.py against a real solution: `sirad render` of the Cornell box,
its PLY read here by the layout sirad writes (scene/ply.cpp), and the OBJ and MTL checked face by
face: every patch once, at its place moved 1e-5 of the extent along its own normal, with its
reflectance and emission, its back black, and the camera carried over.

    solution_to_obj_test.py BUILD_DIR
"""
import math
import os
import struct
import subprocess
import sys
import tempfile

build = sys.argv[1]
here = os.path.dirname(os.path.abspath(__file__))
tool = os.path.join(here, "..", "..", "bench", "cycles", "solution_to_obj.py")


def fail(message):
    sys.exit(f"solution_to_obj_test: {message}")


with tempfile.TemporaryDirectory() as d:
    subprocess.run([os.path.join(build, "sirad"), "render", "cornell", "--patches", "400", "--bundles", "8",
                    "--out", os.path.join(d, "c")], check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    subprocess.run(["/usr/bin/python3", tool, os.path.join(d, "c.ply"), os.path.join(d, "o")], check=True,
                   stderr=subprocess.DEVNULL)
    with open(os.path.join(d, "c.ply"), "rb") as f:
        header = []
        while not header or header[-1] != "end_header":
            header.append(f.readline().decode().strip())
        nv = int(next(h for h in header if h.startswith("element vertex")).split()[2])
        nf = int(next(h for h in header if h.startswith("element face")).split()[2])
        camera = next(h for h in header if h.startswith("comment sirad camera"))[len("comment "):]
        face_properties = [h.split()[-1] for h in header[header.index(next(h for h in header if h.startswith("element face"))):]
                           if h.startswith("property")][1:]
        tail = "<9fB" if face_properties[-1:] == ["sirad_in_gap"] else "<9f"  # in_gap: scenes with gap cuts
        if face_properties[:9] != ["radiosity_r", "radiosity_g", "radiosity_b", "reflectance_r", "reflectance_g",
                                   "reflectance_b", "emission_r", "emission_g", "emission_b"]:
            fail(f"the PLY's face layout changed ({face_properties}): update this test")
        vertices = [struct.unpack("<3f3B", f.read(15))[:3] for _ in range(nv)]
        faces = []
        for _ in range(nf):
            n = f.read(1)[0]
            idx = struct.unpack(f"<{n}i", f.read(4 * n))
            values = struct.unpack(tail, f.read(struct.calcsize(tail)))
            faces.append(([vertices[i] for i in idx], values[3:9]))
    obj_vertices, obj_faces, current, camera_line = [], [], None, None
    with open(os.path.join(d, "o.obj")) as f:
        for line in f:
            w = line.split()
            if line.startswith("# sirad camera"):
                camera_line = line[2:].strip()
            elif w and w[0] == "v":
                obj_vertices.append(tuple(float(x) for x in w[1:4]))
            elif w and w[0] == "usemtl":
                current = w[1]
            elif w and w[0] == "f":
                obj_faces.append(([obj_vertices[int(x) - 1] for x in w[1:]], current))
    materials, name = {}, None
    with open(os.path.join(d, "o.mtl")) as f:
        for line in f:
            w = line.split()
            if w and w[0] == "newmtl":
                name = w[1]
                materials[name] = {}
            elif w:
                materials[name][w[0]] = w[1:]
    if camera_line != camera:
        fail(f"camera {camera_line!r}, the PLY's {camera!r}")
    if len(obj_faces) != nf:
        fail(f"{len(obj_faces)} faces for {nf} patches")
    extent = max(max(v[a] for v in vertices) - min(v[a] for v in vertices) for a in range(3))
    for m in materials.values():
        if m.get("sirad_back") != ["black"]:
            fail(f"a material without `sirad_back black`: {m}")

    def key(points):
        return tuple(sorted(tuple(round(x / extent, 3) for x in p) for p in points))

    by_place = {}
    for points, m in obj_faces:
        by_place.setdefault(key(points), []).append((points, m))
    for points, values in faces:
        a, b, c = points[0], points[1], points[2]
        u = [b[i] - a[i] for i in range(3)]
        v = [c[i] - a[i] for i in range(3)]
        n = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]
        length = math.sqrt(sum(x * x for x in n))
        want = [tuple(p[i] + n[i] / length * 1e-5 * extent for i in range(3)) for p in points]
        found = [(q, m) for q, m in by_place.get(key(points), [])
                 if all(max(abs(q[k][i] - want[k][i]) for i in range(3)) < 1e-7 * extent for k in range(len(q)))]
        if len(found) != 1:
            fail(f"patch at {points}: {len(found)} OBJ faces at its place moved along its normal")
        m = materials[found[0][1]]
        kd = [float(x) for x in m["Kd"]]
        ke = [float(x) for x in m["Ke"]]
        if max(abs(kd[i] - values[i]) for i in range(3)) > 1e-6 or max(abs(ke[i] - values[3 + i]) for i in range(3)) > 1e-5:
            fail(f"patch at {points}: Kd {kd} Ke {ke}, the PLY's {values}")
print(f"solution_to_obj_test: {nf} patches, {len(materials)} materials: ok")
