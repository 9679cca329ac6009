#!/usr/bin/python3
"""sirad's own mesh, as a solution PLY holds it, as an OBJ for render_obj.py.

    bench/cycles/solution_to_obj.py SOLUTION.ply OUT   (writes OUT.obj and OUT.mtl)

Cycles then renders the patches sirad solved, with sirad's materials and sidedness, so that the
difference between `sirad image` of the solution and this render is sirad's transport and its
patch-wise solution alone, not how sirad reads the scene (twins kept or culled, cuts, contacts):
compare it with render_obj.py of the scene's own OBJ to tell the two apart (bench/RESULTS.md,
"Cycles on sirad's own mesh").

- Each patch is one face with its PLY reflectance and emission (materials shared by value).
- A back is black and absorbing (MTL `sirad_back black`): in sirad's model a ray that meets a back
  face first sees the background (DESIGN.md section 1).
- Each face is moved 1e-5 of the scene's extent along its normal: where two faces lie at one place
  facing apart (a face and its kept twin, a zero-thickness wall's two planes), each side then shows
  its own face's front, as the coincident-face rule has it; Cycles would otherwise pick either.
- The PLY's `# sirad camera` comment becomes the OBJ's.
"""
import math
import struct
import sys

PUSH = 1e-5  # of the scene's extent


def read_solution(path):
    types = {"float": "f", "uchar": "B", "int": "i", "uint": "I"}
    with open(path, "rb") as f:
        if f.readline().strip() != b"ply":
            sys.exit(f"solution_to_obj.py: {path}: not a PLY file")
        camera, elements, current = None, [], None
        while True:
            line = f.readline()
            if not line:
                sys.exit(f"solution_to_obj.py: {path}: the header has no end_header")
            w = line.decode("ascii", "replace").split()
            if not w:
                continue
            if w[0] == "format" and w[1] != "binary_little_endian":
                sys.exit(f"solution_to_obj.py: {path}: {w[1]}: only sirad's binary_little_endian PLY is read")
            elif w[0] == "comment" and w[1:3] == ["sirad", "camera"]:
                camera = " ".join(w[1:])
            elif w[0] == "element":
                current = (w[1], int(w[2]), [])
                elements.append(current)
            elif w[0] == "property":
                current[2].append(w[1:])
            elif w[0] == "end_header":
                break
        data = {}
        for name, count, props in elements:
            if name == "vertex":
                if any(p[0] == "list" for p in props):
                    sys.exit(f"solution_to_obj.py: {path}: a vertex list property")
                fmt = "<" + "".join(types[p[0]] for p in props)
                size = struct.calcsize(fmt)
                rows = [struct.unpack(fmt, f.read(size)) for _ in range(count)]
                names = [p[-1] for p in props]
                data["vertex"] = [tuple(r[names.index(a)] for a in "xyz") for r in rows]
            elif name == "face":
                if props[0][:3] != ["list", "uchar", "int"]:
                    sys.exit(f"solution_to_obj.py: {path}: the face's first property is not its vertex list")
                rest = props[1:]
                fmt = "<" + "".join(types[p[0]] for p in rest)
                size = struct.calcsize(fmt)
                names = [p[-1] for p in rest]
                want = ["reflectance_r", "reflectance_g", "reflectance_b", "emission_r", "emission_g", "emission_b"]
                missing = [w for w in want if w not in names]
                if missing:
                    sys.exit(f"solution_to_obj.py: {path}: the faces have no {', '.join(missing)}: not a sirad solution")
                faces = []
                for _ in range(count):
                    n = f.read(1)[0]
                    idx = struct.unpack(f"<{n}i", f.read(4 * n))
                    r = struct.unpack(fmt, f.read(size))
                    faces.append((idx, tuple(round(r[names.index(w)], 6) for w in want)))
                data["face"] = faces
            else:
                sys.exit(f"solution_to_obj.py: {path}: element {name}: not a sirad solution")
    return data["vertex"], data["face"], camera


def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    vertices, faces, camera = read_solution(sys.argv[1])
    out = sys.argv[2]
    extent = max(max(v[a] for v in vertices) - min(v[a] for v in vertices) for a in range(3))
    materials, pushed = {}, []
    for idx, material in faces:
        p = [vertices[i] for i in idx]
        normal = [0.0, 0.0, 0.0]  # Newell's
        for k in range(len(p)):
            c = cross(p[k], p[(k + 1) % len(p)])
            normal = [normal[a] + c[a] for a in range(3)]
        length = math.sqrt(sum(x * x for x in normal))
        if not length > 0:
            continue  # no area, nothing to render
        name = materials.setdefault(material, f"m{len(materials)}")
        move = [x / length * PUSH * extent for x in normal]
        pushed.append((name, [tuple(v[a] + move[a] for a in range(3)) for v in p]))
    pushed.sort(key=lambda face: face[0])
    with open(out + ".obj", "w") as o:
        if camera:
            o.write(f"# {camera}\n")
        o.write(f"mtllib {out.rsplit('/', 1)[-1]}.mtl\n")
        for _, p in pushed:
            for v in p:
                o.write(f"v {v[0]!r} {v[1]!r} {v[2]!r}\n")
        first, current = 1, None
        for name, p in pushed:
            if name != current:
                o.write(f"usemtl {name}\n")
                current = name
            o.write("f " + " ".join(str(first + k) for k in range(len(p))) + "\n")
            first += len(p)
    with open(out + ".mtl", "w") as o:
        for (r, g, b, er, eg, eb), name in materials.items():
            o.write(f"newmtl {name}\nKd {r} {g} {b}\nKe {er} {eg} {eb}\nsirad_back black\n")
    print(f"solution_to_obj.py: {len(pushed)} faces, {len(materials)} materials -> {out}.obj", file=sys.stderr)


if __name__ == "__main__":
    main()
