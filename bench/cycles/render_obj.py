# A converged path-traced reference of a sirad OBJ scene with Blender's Cycles (headless), set
# up to match sirad's model and image: the OBJ's faces as they are (no axis conversion), Kd as
# a diffuse BSDF, Ke as emission of that radiance (a pixel that sees it shows Ke) plus Kd, a
# black world, the OBJ's `# sirad camera` (vertical field of view, sensor fitted to the height),
# a box pixel filter of one pixel (each pixel the mean over its square, as sirad), 64 diffuse
# bounces and nothing clamped, no denoising, no adaptive sampling; linear float EXR, and a PNG
# beside it.
#   blender -b --factory-startup --python bench/cycles/render_obj.py -- SCENE.obj OUT.exr W H SPP [SEED [passes]]
# With `passes` the EXR is multilayer with Cycles' diffuse passes beside the combined image
# (ViewLayer.DiffDir, DiffInd, DiffCol, Emit, each R G B): what the camera sees emitted plus the
# light reflected straight from the emitters is Emit + DiffDir x DiffCol, the rest DiffInd x
# DiffCol, what sirad image writes as its `direct` and `indirect` passes
# (bench/image_bench.cpp --reference-passes compares them).
# (Debian's `blender` 3.4; deploy/install-deps.sh does not install it: apt-get install blender.)
# The figures of bench/RESULTS.md ("Images against Cycles") used SPP 4096 at 128 x 128 and 2048
# at 512 x 512, seeds 0 and 2 for the two references, 1 for the candidates.
# Prints "cycles: W x H, SPP spp, SECONDS s" (the render's own time).
import math
import os
import sys
import time

import bpy
import mathutils

args = sys.argv[sys.argv.index("--") + 1:]
obj_path, out_path, width, height, spp = args[0], args[1], int(args[2]), int(args[3]), int(args[4])
seed = int(args[5]) if len(args) > 5 else 0
passes = len(args) > 6 and args[6] == "passes"

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
            materials[name] = {"Kd": (0.8, 0.8, 0.8), "Ke": (0.0, 0.0, 0.0)}
        elif w[0] in ("Kd", "Ke"):
            materials[name][w[0]] = tuple(float(x) for x in w[1:4])

bpy.ops.object.select_all(action="SELECT")
bpy.ops.object.delete()
names = sorted(materials)
mesh = bpy.data.meshes.new("scene")
mesh.from_pydata(verts, [], [f[0] for f in faces])
mesh.update()
for n in names:
    m = bpy.data.materials.new(n)
    m.use_nodes = True
    nt = m.node_tree
    nt.nodes.clear()
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    diffuse = nt.nodes.new("ShaderNodeBsdfDiffuse")
    diffuse.inputs["Color"].default_value = (*materials[n]["Kd"], 1.0)
    ke = materials[n]["Ke"]
    if max(ke) > 0:
        emission = nt.nodes.new("ShaderNodeEmission")
        emission.inputs["Color"].default_value = (*ke, 1.0)
        emission.inputs["Strength"].default_value = 1.0
        add = nt.nodes.new("ShaderNodeAddShader")
        nt.links.new(emission.outputs[0], add.inputs[0])
        nt.links.new(diffuse.outputs[0], add.inputs[1])
        nt.links.new(add.outputs[0], out.inputs["Surface"])
    else:
        nt.links.new(diffuse.outputs[0], out.inputs["Surface"])
    mesh.materials.append(m)
for poly, (idx, mat) in zip(mesh.polygons, faces):
    poly.material_index = names.index(mat)
    poly.use_smooth = False
obj = bpy.data.objects.new("scene", mesh)
bpy.context.scene.collection.objects.link(obj)

# The camera: eye, look, up, vertical fov, the sensor fitted to the height.
c = {camera[i]: camera[i + 1:i + 4] for i in range(0, len(camera), 4) if camera[i] in ("eye", "look", "up")}
fov = float(camera[camera.index("fov") + 1])
eye = mathutils.Vector([float(x) for x in c["eye"]])
look = mathutils.Vector([float(x) for x in c["look"]])
up = mathutils.Vector([float(x) for x in c["up"]])
cam_data = bpy.data.cameras.new("camera")
cam_data.sensor_fit = "VERTICAL"
cam_data.angle_y = math.radians(fov)
cam_data.clip_start = 1e-4  # nothing of the scene clipped (Blender's default ends at 100 or 1000 units)
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
scene.world = bpy.data.worlds.new("black")
scene.world.use_nodes = True
scene.world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.0
scene.render.engine = "CYCLES"
cy = scene.cycles
cy.device = "CPU"
cy.samples = spp
cy.use_adaptive_sampling = False
cy.use_denoising = False
cy.seed = seed
cy.max_bounces = 64
cy.diffuse_bounces = 64
cy.glossy_bounces = 0
cy.transmission_bounces = 0
cy.volume_bounces = 0
cy.transparent_max_bounces = 0
cy.caustics_reflective = False
cy.caustics_refractive = False
cy.sample_clamp_direct = 0.0
cy.sample_clamp_indirect = 0.0
cy.pixel_filter_type = "BOX"
cy.filter_width = 1.0
scene.render.resolution_x = width
scene.render.resolution_y = height
scene.render.resolution_percentage = 100
scene.render.film_transparent = False
scene.view_settings.view_transform = "Standard"
scene.view_settings.look = "None"
scene.view_settings.exposure = 0.0
scene.view_settings.gamma = 1.0
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
