#!/usr/bin/python3
"""Prepares an OBJ that Blender exported for bench/cycles/render_obj.py.

    bench/cycles/prepare_blender_obj.py IN.obj OUT.obj "eye X Y Z look X Y Z up X Y Z fov DEG" [--move OBJECT DX DY DZ]...

Writes OUT.obj and OUT.mtl (never over the input): the camera as a `# sirad camera` line (the
camera sirad takes from the glb: the `sirad.camera` attribute of the EXR it writes); a bare
`usemtl` (Blender's exporter writes one for an object or a Boolean's cut faces without a
material) as the material `sirad_default`, sirad's default (Kd 0.8); and each `--move` object's
vertices moved by (DX, DY, DZ). Cycles treats every face two-sided and has no rule for two faces
at one place: the two planes of a zero-thickness wall with a different material on each side
z-fight there, where sirad shows each room its own side (DESIGN.md, "Coincident faces"); moving
one plane 1 mm towards the side it faces gives Cycles the same wall.
"""
import os
import sys


def main(argv):
    if len(argv) < 3:
        sys.exit(__doc__)
    src, dst, camera = argv[0], argv[1], argv[2]
    moves, rest = {}, argv[3:]
    while rest:
        if rest[0] != "--move" or len(rest) < 5:
            sys.exit(f"prepare_blender_obj.py: expected --move OBJECT DX DY DZ, got {' '.join(rest[:5])!r}")
        moves[rest[1]] = tuple(float(x) for x in rest[2:5])
        rest = rest[5:]
    if os.path.abspath(src) == os.path.abspath(dst):
        sys.exit("prepare_blender_obj.py: OUT.obj must not be IN.obj")
    mtl_in, mtl_out = None, os.path.splitext(dst)[0] + ".mtl"
    lines, obj, moved = [f"# sirad camera {camera}\n"], None, set()
    with open(src) as f:
        for line in f:
            w = line.split()
            if w and w[0] == "mtllib":
                mtl_in = os.path.join(os.path.dirname(src), w[1])
                line = f"mtllib {os.path.basename(mtl_out)}\n"
            elif w and w[0] == "o":
                obj = w[1] if len(w) > 1 else None
            elif w and w[0] == "usemtl" and len(w) == 1:
                line = "usemtl sirad_default\n"
            elif w and w[0] == "v" and obj in moves:
                d = moves[obj]
                line = "v " + " ".join(f"{float(w[1 + k]) + d[k]:.6f}" for k in range(3)) + "\n"
                moved.add(obj)
            lines.append(line)
    missing = set(moves) - moved
    if missing:
        sys.exit(f"prepare_blender_obj.py: {src}: no object {sorted(missing)} to move")
    if mtl_in is None:
        sys.exit(f"prepare_blender_obj.py: {src}: no mtllib")
    with open(mtl_in) as f:
        mtl = f.read()
    mtl += "\nnewmtl sirad_default\nKd 0.8 0.8 0.8\nKe 0 0 0\n"
    for path, text in ((mtl_out, mtl), (dst, "".join(lines))):
        with open(path + ".tmp", "w") as f:
            f.write(text)
        os.replace(path + ".tmp", path)


if __name__ == "__main__":
    main(sys.argv[1:])
