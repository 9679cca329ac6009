# Cycles' bake of a sirad baked glb (NAME-baked.glb of `sirad bake`) to the same lightmap layout,
# texel by texel what sirad's NAME-lightmap.exr holds: the radiance leaving each texel's surface,
# emission included (a diffuse surface's COMBINED bake), linear, float EXR.
#   blender -b --factory-startup --python bench/cycles/bake_glb.py -- NAME-baked.glb OUT.exr W H SPP [SEED]
# W x H is the lightmap's size (sirad bake prints it). Set up as render_obj.py sets up a render:
# the glb's faces as they are, each material's `sirad_reflectance` as a diffuse BSDF and its
# `sirad_emission` as emission of that radiance, a black world, every diffuse bounce (64) and
# nothing clamped; the scene scaled to an extent of 1 and each emitting triangle cut into N x N
# pieces so that Cycles samples it by area (render_obj.py says why). The bake's target is the
# glb's TEXCOORD_1 (glTF's v runs down, Blender's up), with no margin: texels that no face
# covers stay at alpha 0 (bench/lightmap_bench.cpp leaves them out).
# Prints "cycles bake: W x H, SPP spp, SECONDS s" (the bake's own time).
import json
import math
import os
import struct
import sys
import time

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import cycles_setup  # noqa: E402

args = sys.argv[sys.argv.index("--") + 1:]
glb_path, out_path, width, height, spp = args[0], args[1], int(args[2]), int(args[3]), int(args[4])
seed = int(args[5]) if len(args) > 5 else 0

# The glb, read here: its meshes' triangles with POSITION and TEXCOORD_1, and their materials.
with open(glb_path, "rb") as f:
    data = f.read()
magic, _, _ = struct.unpack_from("<4sII", data, 0)
if magic != b"glTF":
    sys.exit(f"bake_glb.py: {glb_path}: not a glb")
json_length, _ = struct.unpack_from("<I4s", data, 12)
gltf = json.loads(data[20:20 + json_length])
bin_start = 20 + json_length + 8
blob = data[bin_start:]


def accessor(i):
    a = gltf["accessors"][i]
    view = gltf["bufferViews"][a["bufferView"]]
    count = {"SCALAR": 1, "VEC2": 2, "VEC3": 3}[a["type"]]
    fmt = {5126: "f", 5125: "I", 5123: "H", 5121: "B"}[a["componentType"]]
    size = struct.calcsize(fmt)
    stride = view.get("byteStride", size * count)
    start = view.get("byteOffset", 0) + a.get("byteOffset", 0)
    return [struct.unpack_from("<" + fmt * count, blob, start + k * stride) for k in range(a["count"])]


for node in gltf.get("nodes", []):
    if "mesh" in node and any(k in node for k in ("matrix", "translation", "rotation", "scale")):
        sys.exit("bake_glb.py: a mesh node with a transform: not a glb that sirad bake wrote")
materials = []
for m in gltf["materials"]:
    extras = m.get("extras", {})
    if "sirad_reflectance" not in extras:
        sys.exit(f"bake_glb.py: material {m.get('name')!r} has no sirad_reflectance: not a glb that sirad bake wrote")
    materials.append((m.get("name", "material"), tuple(extras["sirad_reflectance"]), tuple(extras.get("sirad_emission", (0, 0, 0)))))
triangles = []  # (three points, three UVs, material)
for mesh in gltf["meshes"]:
    for prim in mesh["primitives"]:
        if "TEXCOORD_1" not in prim["attributes"]:
            sys.exit(f"bake_glb.py: mesh {mesh.get('name')!r} has no TEXCOORD_1")
        p = accessor(prim["attributes"]["POSITION"])
        uv = accessor(prim["attributes"]["TEXCOORD_1"])
        idx = [i[0] for i in accessor(prim["indices"])]
        for k in range(0, len(idx), 3):
            t = idx[k:k + 3]
            triangles.append(([p[i] for i in t], [(uv[i][0], 1.0 - uv[i][1]) for i in t], prim["material"]))

# Scaled to an extent of 1; emitting triangles cut so that Cycles samples them by area.
low = [min(q[a] for t in triangles for q in t[0]) for a in range(3)]
extent = max(max(q[a] for t in triangles for q in t[0]) - low[a] for a in range(3))
scale = 1.0 / extent


def lerp3(a, b, c, s, t):  # the point (s, t) of triangle abc, s + t <= 1
    return tuple(a[i] + (b[i] - a[i]) * s + (c[i] - a[i]) * t for i in range(len(a)))


def pieces(n):
    """Triangle abc cut into n^2 triangles, as barycentric (s, t) corners."""
    out = []
    for i in range(n):
        for j in range(n - i):
            out.append([(i / n, j / n), ((i + 1) / n, j / n), (i / n, (j + 1) / n)])
            if i + j + 1 < n:
                out.append([((i + 1) / n, j / n), ((i + 1) / n, (j + 1) / n), (i / n, (j + 1) / n)])
    return out


verts, faces, uvs, face_material = [], [], [], []
cuts = []
for points, uv, material in triangles:
    points = [tuple(x * scale for x in q) for q in points]
    n = 1
    if max(materials[material][2]) > 0:
        longest = max(math.dist(points[a], points[b]) for a, b in ((0, 1), (1, 2), (2, 0)))
        e1 = [points[1][i] - points[0][i] for i in range(3)]
        e2 = [points[2][i] - points[0][i] for i in range(3)]
        cr = (e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0])
        twice_area = math.sqrt(sum(x * x for x in cr))
        n = min(64, cycles_setup.area_sampling_cuts(longest, twice_area))
        cuts.append(n)
    for piece in pieces(n):
        base = len(verts)
        for s, t in piece:
            verts.append(lerp3(*points, s, t))
            uvs.append(lerp3(*uv, s, t))
        faces.append((base, base + 1, base + 2))
        face_material.append(material)
print(f"bake_glb.py: {len(triangles)} triangles, scaled by {scale:.6g}; {len(cuts)} emitting triangles cut into "
      f"{min(cuts, default=0)} to {max(cuts, default=0)} a side")

bpy.ops.object.select_all(action="SELECT")
bpy.ops.object.delete()
mesh = bpy.data.meshes.new("scene")
mesh.from_pydata(verts, [], faces)
mesh.update()
layer = mesh.uv_layers.new(name="lightmap")
for poly in mesh.polygons:
    poly.use_smooth = False
    poly.material_index = face_material[poly.index]
    for loop in poly.loop_indices:
        layer.data[loop].uv = uvs[mesh.loops[loop].vertex_index][:2]
target = bpy.data.images.new("bake", width=width, height=height, alpha=True, float_buffer=True)
target.generated_color = (0.0, 0.0, 0.0, 0.0)
for name, kd, ke in materials:
    m = cycles_setup.material(name, kd, ke)
    nt = m.node_tree
    texture = nt.nodes.new("ShaderNodeTexImage")  # the bake's target, selected and active
    texture.image = target
    for node in nt.nodes:
        node.select = False
    texture.select = True
    nt.nodes.active = texture
    mesh.materials.append(m)
obj = bpy.data.objects.new("scene", mesh)
bpy.context.scene.collection.objects.link(obj)
bpy.context.view_layer.objects.active = obj
obj.select_set(True)

scene = bpy.context.scene
cycles_setup.converged(scene, spp, seed)
bake = scene.render.bake
bake.margin = 0
bake.use_pass_direct = True
bake.use_pass_indirect = True
bake.use_pass_diffuse = True
bake.use_pass_emit = True
bake.target = "IMAGE_TEXTURES"
start = time.time()
bpy.ops.object.bake(type="COMBINED", uv_layer="lightmap", margin=0)
print(f"cycles bake: {width} x {height}, {spp} spp, {time.time() - start:.2f} s")
target.filepath_raw = out_path
target.file_format = "OPEN_EXR"
scene.render.image_settings.file_format = "OPEN_EXR"
scene.render.image_settings.color_depth = "32"
scene.render.image_settings.color_mode = "RGBA"
target.save_render(out_path, scene=scene)
