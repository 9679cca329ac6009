# A converged path-traced reference of a sirad OBJ scene with Blender's Cycles (headless), set
# up to match sirad's model and image: the OBJ's faces as they are (no axis conversion), Kd as
# a diffuse BSDF, Ke as emission of that radiance (a pixel that sees it shows Ke) plus Kd, a
# black world, the OBJ's `# sirad camera` (vertical field of view, sensor fitted to the height),
# a box pixel filter of one pixel (each pixel the mean over its square, as sirad), 64 diffuse
# bounces and nothing clamped, no denoising, no adaptive sampling; linear float EXR, and a PNG
# beside it.
#   blender -b --factory-startup --python bench/cycles/render_obj.py -- SCENE.obj OUT.exr W H SPP [SEED [passes] [asis]]
# With `passes` the EXR is multilayer with Cycles' diffuse passes beside the combined image
# (ViewLayer.DiffDir, DiffInd, DiffCol, Emit, each R G B): what the camera sees emitted plus the
# light reflected straight from the emitters is Emit + DiffDir x DiffCol, the rest DiffInd x
# DiffCol, what sirad image writes as its `direct` and `indirect` passes
# (bench/image_bench.cpp --reference-passes compares them).
# An MTL line `sirad_back black` (written by solution_to_obj.py) makes a material's back side black
# and absorbing, as the back of a one-sided face is in sirad's model: Cycles then renders sirad's
# own mesh with sirad's sidedness, so that the difference from sirad's image is its transport and
# patches alone, not how it reads the scene.
# (Debian's `blender` 3.4; deploy/install-deps.sh does not install it: apt-get install blender.)
# The figures of bench/RESULTS.md ("Images against Cycles") used SPP 4096 at 128 x 128 and 2048
# at 512 x 512, seeds 0 and 2 for the two references, 1 for the candidates.
#
# Emitters are sampled by area. Cycles 3.4 samples an emitting triangle by solid angle (Arvo's
# method, in single precision with approximate arc cosines) where the point it lights is closer
# to the triangle's plane than the triangle's longest edge, and by area elsewhere; its
# "distance" is the true one divided by the length of the triangle's unnormalised normal (twice
# its area), so which method it takes depends on the scene's units. The solid-angle path is
# biased dark: a wall beside a ceiling light (bench/cycles/wall) by 0.2 % at mid-height to 2.9 %
# near the light's plane, against Lambert's formula, and by 14 % and more on the Cornell box's
# walls when its light is cut into smaller triangles in millimetres. So the scene is scaled to
# an extent of 1 (radiance does not depend on scale) and each emitting triangle or quad is cut
# into the fewest N x N pieces for which Cycles takes the area path everywhere but within 1e-4
# of the scene's extent of an emitter's plane (longest edge x twice the area <= 1e-4 per piece);
# the wall then matches Lambert's formula to 0.03 % in every pixel row. Option `asis` keeps
# Cycles' own choice (the references before 2026-12-05).
# Prints "cycles: W x H, SPP spp, SECONDS s" (the render's own time).
import math
import os
import sys
import time

import bpy
import mathutils

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import cycles_setup  # noqa: E402

args = sys.argv[sys.argv.index("--") + 1:]
obj_path, out_path, width, height, spp = args[0], args[1], int(args[2]), int(args[3]), int(args[4])
seed = int(args[5]) if len(args) > 5 else 0
options = args[6:]
passes = "passes" in options
asis = "asis" in options
for o in options:
    if o not in ("passes", "asis"):
        sys.exit(f"render_obj.py: unknown option {o!r} (passes, asis)")

# The OBJ and its MTL, read here (Blender's importer converts axes and merges materials).
verts, faces, camera = [], [], None
materials, current, mtl_file = {}, None, None
with open(obj_path) as f:
    for line in f:
        w = line.split()
        if not w:
            continue
        if w[0] == "#" and len(w) > 2 and w[1] == "sirad" and w[2] == "camera":
            camera = w[3:]
        elif w[0] == "mtllib":
            mtl_file = os.path.join(os.path.dirname(obj_path), w[1])
        elif w[0] == "usemtl":
            current = w[1]
        elif w[0] == "v":
            verts.append(tuple(float(x) for x in w[1:4]))
        elif w[0] == "f":
            idx = [int(p.split("/")[0]) for p in w[1:]]
            idx = [i - 1 if i > 0 else len(verts) + i for i in idx]
            faces.append((idx, current))
name = None
with open(mtl_file) as f:
    for line in f:
        w = line.split()
        if not w:
            continue
        if w[0] == "newmtl":
            name = w[1]
            materials[name] = {"Kd": (0.8, 0.8, 0.8), "Ke": (0.0, 0.0, 0.0), "black_back": False}
        elif w[0] in ("Kd", "Ke"):
            materials[name][w[0]] = tuple(float(x) for x in w[1:4])
        elif w[0] == "sirad_back":
            if w[1:] != ["black"]:
                sys.exit(f"render_obj.py: {mtl_file}: sirad_back takes `black` only, not {' '.join(w[1:])!r}")
            materials[name]["black_back"] = True



def cut(idx, n):
    """A triangle or quad of vertex indices cut into n x n pieces (new vertices appended)."""
    p = [mathutils.Vector(verts[i]) for i in idx]
    if len(p) == 3:
        p.append(p[2])  # a quad whose last edge has no length: its pieces along it are triangles
    grid = {}
    for i in range(n + 1):
        for j in range(n + 1):
            s, t = i / n, j / n
            verts.append(tuple(p[0] * (1 - s) * (1 - t) + p[1] * s * (1 - t) + p[2] * s * t + p[3] * (1 - s) * t))
            grid[i, j] = len(verts) - 1
    pieces = []
    for i in range(n):
        for j in range(n):
            piece = [grid[i, j], grid[i + 1, j], grid[i + 1, j + 1], grid[i, j + 1]]
            pieces.append(piece[:3] if len(idx) == 3 and j == n - 1 else piece)
    return pieces


def pieces_for_area_sampling(idx):
    """The N for which Cycles samples each of a face's N x N pieces by area (see the top)."""
    p = [mathutils.Vector(verts[i]) for i in idx]
    longest = max((a - b).length for a in p for b in p)  # a quad's diagonal is an edge of its triangles
    twice_area = (p[1] - p[0]).cross(p[2] - p[0]).length
    if len(p) == 4:
        twice_area = max(twice_area, (p[2] - p[0]).cross(p[3] - p[0]).length)
    return cycles_setup.area_sampling_cuts(longest, twice_area)


if not asis:
    low = [min(v[a] for v in verts) for a in range(3)]
    extent = max(max(v[a] for v in verts) - low[a] for a in range(3))
    if not extent > 0:
        sys.exit(f"render_obj.py: {obj_path}: the scene has no extent")
    scale = 1.0 / extent
    verts = [tuple(x * scale for x in v) for v in verts]
    cut_faces, cuts = [], []
    for idx, mat in faces:
        if max(materials[mat]["Ke"]) > 0 and len(idx) in (3, 4):
            n = min(pieces_for_area_sampling(idx), 64)
            cuts.append(n)
            cut_faces += [(piece, mat) for piece in cut(idx, n)]
        else:
            if max(materials[mat]["Ke"]) > 0:
                print(f"render_obj.py: an emitting face of {len(idx)} corners is left whole (Cycles may sample it by solid angle)")
            cut_faces.append((idx, mat))
    faces = cut_faces
    print(f"render_obj.py: scene scaled by {scale:.6g}; {len(cuts)} emitting faces cut into {min(cuts, default=0)} to {max(cuts, default=0)} a side")

bpy.ops.object.select_all(action="SELECT")
bpy.ops.object.delete()
names = sorted(materials)
mesh = bpy.data.meshes.new("scene")
mesh.from_pydata(verts, [], [f[0] for f in faces])
mesh.update()
for n in names:
    m = cycles_setup.material(n, materials[n]["Kd"], materials[n]["Ke"], materials[n]["black_back"])
    mesh.materials.append(m)
for poly, (idx, mat) in zip(mesh.polygons, faces):
    poly.material_index = names.index(mat)
    poly.use_smooth = False
obj = bpy.data.objects.new("scene", mesh)
bpy.context.scene.collection.objects.link(obj)

# The camera: eye, look, up, vertical fov, the sensor fitted to the height.
c = {camera[i]: camera[i + 1:i + 4] for i in range(0, len(camera), 4) if camera[i] in ("eye", "look", "up")}
fov = float(camera[camera.index("fov") + 1])
eye = mathutils.Vector([float(x) for x in c["eye"]]) * (1.0 if asis else scale)
look = mathutils.Vector([float(x) for x in c["look"]]) * (1.0 if asis else scale)
up = mathutils.Vector([float(x) for x in c["up"]])
cam_data = bpy.data.cameras.new("camera")
cam_data.sensor_fit = "VERTICAL"
cam_data.angle_y = math.radians(fov)
cam_data.clip_start = 1e-6  # nothing of the scene clipped (Blender's default ends at 100 or 1000 units)
cam_data.clip_end = 1e9
cam = bpy.data.objects.new("camera", cam_data)
forward = (look - eye).normalized()
right = forward.cross(up).normalized()
true_up = right.cross(forward)
rot = mathutils.Matrix((right, true_up, -forward)).transposed()  # camera looks along -Z, up +Y
cam.matrix_world = mathutils.Matrix.Translation(eye) @ rot.to_4x4()
bpy.context.scene.collection.objects.link(cam)

scene = bpy.context.scene
scene.camera = cam
cycles_setup.converged(scene, spp, seed)
cy = scene.cycles
cy.pixel_filter_type = "BOX"
cy.filter_width = 1.0
scene.render.resolution_x = width
scene.render.resolution_y = height
scene.render.resolution_percentage = 100
scene.render.film_transparent = False
scene.render.image_settings.file_format = "OPEN_EXR_MULTILAYER" if passes else "OPEN_EXR"
if passes:
    layer = scene.view_layers[0]
    layer.use_pass_diffuse_direct = True
    layer.use_pass_diffuse_indirect = True
    layer.use_pass_diffuse_color = True
    layer.use_pass_emit = True
scene.render.image_settings.color_depth = "32"
scene.render.image_settings.color_mode = "RGB"
scene.render.filepath = out_path
start = time.time()
bpy.ops.render.render(write_still=True)
print(f"cycles: {width} x {height}, {spp} spp, {time.time() - start:.2f} s")
# A PNG beside it for a quick look (sRGB, the Standard view transform).
scene.render.image_settings.file_format = "PNG"
scene.render.image_settings.color_depth = "8"
bpy.data.images["Render Result"].save_render(os.path.splitext(out_path)[0] + ".png", scene=scene)
