# Builds tests/data/blender/room.glb and room.obj (+ room.mtl) with Blender, headless:
#   blender -b --factory-startup --python tests/data/blender/make_room.py -- OUTDIR
# A room made as a Blender user would: the default cube scaled up (normals out, materials
# two-sided as Blender's default), a lamp plane with an Emission strength, a block under an
# empty that turns and lifts it (a transform hierarchy), and a camera inside. Both files are
# exported by Blender's own exporters (glTF 2.0 and OBJ), the test data of tests/scene/gltf_test.cpp.
import sys, math, os
import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from blender_scene import clear_scene, material  # noqa: E402

out = sys.argv[sys.argv.index("--") + 1] if "--" in sys.argv else os.path.dirname(os.path.abspath(__file__))
clear_scene()

# Blender is Z-up; both exporters write Y-up.
bpy.ops.mesh.primitive_cube_add(size=2.0, location=(0.0, 0.0, 1.5))
room = bpy.context.object
room.name = "Room"
room.scale = (2.0, 2.0, 1.5)
room.data.materials.append(material("Plaster", (0.7, 0.7, 0.7)))

bpy.ops.mesh.primitive_plane_add(size=1.0, location=(0.0, 0.0, 2.95))
lamp = bpy.context.object
lamp.name = "Lamp"
lamp.rotation_euler = (math.pi, 0.0, 0.0)  # facing down
lamp.data.materials.append(material("LampGlow", (0.5, 0.5, 0.5), (1.0, 0.95, 0.9), 6.0))

bpy.ops.object.empty_add(location=(0.6, -0.4, 0.0))
pivot = bpy.context.object
pivot.name = "Pivot"
pivot.rotation_euler = (0.0, 0.0, math.radians(30.0))
bpy.ops.mesh.primitive_cube_add(size=1.0, location=(0.0, 0.0, 0.5))
block = bpy.context.object
block.name = "Block"
block.data.materials.append(material("Red", (0.8, 0.2, 0.15)))
block.parent = pivot

bpy.ops.object.camera_add(location=(-1.7, 1.7, 1.6))
cam = bpy.context.object
cam.name = "View"
cam.data.sensor_fit = "VERTICAL"
cam.data.angle_y = math.radians(60.0)
direction = bpy.context.scene.objects["Block"].matrix_world.translation - cam.location
cam.rotation_euler = direction.to_track_quat("-Z", "Y").to_euler()
bpy.context.scene.camera = cam
bpy.context.view_layer.update()

bpy.ops.export_scene.gltf(filepath=os.path.join(out, "room.glb"), export_format="GLB", export_cameras=True,
                          export_lights=False, export_apply=True)
bpy.ops.wm.obj_export(filepath=os.path.join(out, "room.obj"), export_materials=True, export_triangulated_mesh=False)
print("wrote", os.path.join(out, "room.glb"), os.path.join(out, "room.obj"))
