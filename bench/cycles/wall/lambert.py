# Each pixel row of a render of wall.obj or ceil.obj (README.md) against Lambert's formula: the
# row's mean radiance and the exact one (8 x 8 points per pixel, the camera of the OBJ's
# `# sirad camera` line as sirad and render_obj.py frame it), and their difference.
#   blender -b --factory-startup --python bench/cycles/wall/lambert.py -- RENDER.exr
import sys

import bpy
import numpy as np

path = sys.argv[sys.argv.index("--") + 1]
image = bpy.data.images.load(path)
w, h = image.size
# Blender's pixels run bottom row first, RGBA.
red = np.array(image.pixels[:], dtype=np.float64).reshape(h, w, 4)[::-1, :, 0]

eye = np.array([0.2, 0.0, 0.5])
forward, up = np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0])
right = np.cross(forward, up)
t = np.tan(np.radians(60.0) / 2)
square = np.array([[-0.5, -0.5, 1], [-0.5, 0.5, 1], [0.5, 0.5, 1], [0.5, -0.5, 1]], dtype=np.float64)
normal = np.array([-1.0, 0.0, 0.0])


def form_factor(points):
    """Lambert's formula from points on the wall (normal -x) to the square."""
    total = np.zeros(len(points))
    for i in range(4):
        a = square[i] - points
        b = square[(i + 1) % 4] - points
        a /= np.linalg.norm(a, axis=1)[:, None]
        b /= np.linalg.norm(b, axis=1)[:, None]
        c = np.cross(a, b)
        c /= np.linalg.norm(c, axis=1)[:, None]
        total += np.arccos(np.clip((a * b).sum(1), -1, 1)) * (c @ normal)
    return np.abs(total) / (2 * np.pi)


sub = (np.arange(8) + 0.5) / 8
for y in range(h):
    xs = (np.arange(w)[:, None] + sub[None, :]).ravel()
    ys = y + sub
    v = np.repeat((1 - ys / h * 2)[None, :], len(xs), 0).ravel()
    u = np.repeat(xs / w * 2 - 1, len(sub))
    d = forward[None, :] + right[None, :] * (u * t)[:, None] + up[None, :] * (v * t)[:, None]
    p = eye[None, :] + d * ((1 - eye[0]) / d[:, 0])[:, None]
    exact = 0.5 * form_factor(p).mean()
    got = red[y].mean()
    print(f"row {y:2d} (z {p[:, 2].mean():.3f}): render {got:.6f}, Lambert {exact:.6f}, {100 * (got / exact - 1):+.2f} %")
