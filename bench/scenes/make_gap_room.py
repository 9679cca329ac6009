# A plain room (5 x 4 x 2.6 m, the default cube scaled, Plaster 0.7, two-sided as Blender's
# default) with a plane lamp 1.2 x 0.6 m emitting on both sides, GAP metres under the ceiling, and
# a camera in a corner looking at the lamp and the walls under it (50 degrees, 3:2): the lamp's
# gap on its own, without the apartment's walls, furniture and other lamps (bench/RESULTS.md,
# "Light that leaves a gap"). GAP 0.5 is the control (nothing cut, no gap).
#   blender -b --factory-startup --python bench/scenes/make_gap_room.py -- OUTDIR NAME GAP
# writes OUTDIR/NAME.glb and NAME.obj (+ .mtl), exported with Blender's defaults.
import math
import os
import sys

import bpy
import mathutils

here = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(here, "..", "..", "tests", "data", "blender"))
from blender_scene import clear_scene, material  # noqa: E402

out, name, gap = sys.argv[sys.argv.index("--") + 1:][:3]
gap = float(gap)
clear_scene()
H = 2.6
bpy.ops.mesh.primitive_cube_add(size=1.0, location=(2.5, 2.0, H / 2))
room = bpy.context.object
room.name = "Room"
room.scale = (5.0, 4.0, H)
bpy.ops.object.transform_apply(location=False, rotation=False, scale=True)
room.data.materials.append(material("Plaster", (0.7, 0.7, 0.7)))
bpy.ops.mesh.primitive_plane_add(size=1.0, location=(2.5, 2.0, H - gap))
lamp = bpy.context.object
lamp.name = "Lamp"
lamp.scale = (1.2, 0.6, 1.0)
lamp.rotation_euler = (math.pi, 0.0, 0.0)  # facing down
bpy.ops.object.transform_apply(location=False, rotation=True, scale=True)
lamp.data.materials.append(material("LampWhite", (0.8, 0.8, 0.8), (1.0, 0.97, 0.92), 8.0))
bpy.ops.object.camera_add(location=(0.4, 0.4, 1.4))
cam = bpy.context.object
cam.name = "View"
cam.data.sensor_fit = "VERTICAL"
cam.data.angle_y = math.radians(50.0)
cam.rotation_euler = (mathutils.Vector((3.2, 2.6, 2.1)) - cam.location).to_track_quat("-Z", "Y").to_euler()
bpy.context.scene.camera = cam
bpy.context.scene.render.resolution_x = 96
bpy.context.scene.render.resolution_y = 64
bpy.context.view_layer.update()
bpy.ops.export_scene.gltf(filepath=os.path.join(out, name + ".glb"), export_format="GLB", export_cameras=True,
                          export_lights=False, export_apply=True)
bpy.ops.wm.obj_export(filepath=os.path.join(out, name + ".obj"), export_materials=True, export_triangulated_mesh=False)
