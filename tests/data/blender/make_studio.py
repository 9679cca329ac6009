# Builds the studio of the Blender corpus (issue 34), headless, the way an architect models:
#   blender -b --factory-startup --python tests/data/blender/make_studio.py -- OUTDIR
# writes OUTDIR/studio.glb (Blender's glTF exporter, its defaults and the camera) and
# OUTDIR/studio.obj + .mtl (Blender's OBJ exporter, its defaults).
#
# What the apartment (make_apartment.py) does not have: the whole building turned 30 degrees on a
# parent empty (no face axis-aligned in the file); a round lamp, a cylinder 3 cm thick whose lid
# is 1 cm under the ceiling (its caps are 32-sided n-gons, which the exporters cut into fans); a
# closet lit only through a door in a 10 cm wall; a free-standing zero-thickness divider of two
# coincident planes, red towards the window and white towards the bed, 1.4 m high; a sky plane
# behind a window. Plan, before the turn (Blender's x, y; z up): the studio x 0..6, y 0..4, 2.7 m
# high; the closet x 4.5..6, y 2.5..4 behind a wall at x 4.45..4.55 (y 2.5..4) and y 2.45..2.55
# (x 4.5..6), its door in the x wall.
import math
import os
import sys

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from blender_scene import box, clear_scene, cut, material, plane_wall, shell  # noqa: E402

out = sys.argv[sys.argv.index("--") + 1] if "--" in sys.argv else os.getcwd()
clear_scene()

H = 2.7
plaster = material("Plaster", (0.78, 0.78, 0.75))
ceiling_white = material("Ceiling", (0.85, 0.85, 0.85))
floor_wood = material("Walnut", (0.35, 0.22, 0.14))
red = material("RedPaint", (0.65, 0.12, 0.1))
white = material("WhitePaint", (0.85, 0.85, 0.82))
linen = material("Linen", (0.7, 0.68, 0.62))
lamp = material("LampDisc", (0.8, 0.8, 0.8), (1.0, 0.9, 0.75), 10.0)
sky = material("Sky", (0.0, 0.0, 0.0), (0.6, 0.75, 1.0), 2.5)

building = bpy.data.objects.new("Building", None)  # the turned parent of everything
bpy.context.collection.objects.link(building)
building.rotation_euler = (0.0, 0.0, math.radians(30.0))
building.location = (1.0, -0.5, 0.0)


south = shell(6.0, 4.0, H, 0.15, floor_wood, ceiling_white, plaster, building)
cut(south, "Window", 1.0, -0.25, 0.8, 3.0, 0.1, 2.2, building)
closet_x = box("ClosetWallX", plaster, 4.45, 2.45, 0.0, 4.55, 4.0, H, building)
box("ClosetWallY", plaster, 4.55, 2.45, 0.0, 6.0, 2.55, H, building)
cut(closet_x, "ClosetDoor", 4.4, 3.0, -0.1, 4.6, 3.8, 2.05, building)

# The divider: two coincident planes, red facing the window (-y), white facing the bed (+y).
pts = [(1.0, 2.0, 0.0), (3.0, 2.0, 0.0), (3.0, 2.0, 1.4), (1.0, 2.0, 1.4)]
plane_wall("DividerRed", red, pts, [(0, 1, 2, 3)], parent=building)  # normal -y (counter-clockwise seen from -y)
plane_wall("DividerWhite", white, pts, [(0, 1, 2, 3)], flip=True, parent=building)

# The round lamp: lid 1 cm under the ceiling.
bpy.ops.mesh.primitive_cylinder_add(vertices=32, radius=0.3, depth=0.03, location=(2.0, 1.2, H - 0.01 - 0.015))
disc = bpy.context.object
disc.name = "LampDisc"
disc.data.materials.append(lamp)
disc.parent = building

box("Bed", linen, 1.2, 2.6, 0.0, 3.2, 3.9, 0.45, building)

bpy.ops.mesh.primitive_plane_add(size=1.0, location=(2.0, -2.0, 1.5))
sky_plane = bpy.context.object
sky_plane.name = "Sky"
sky_plane.scale = (6.0, 3.5, 1.0)
sky_plane.rotation_euler = (-math.pi / 2, 0.0, 0.0)  # normal +y, towards the window
sky_plane.data.materials.append(sky)
sky_plane.parent = building

# The camera: 24 mm, 16:9, by the east wall looking back at the divider and the window.
bpy.ops.object.camera_add(location=(5.6, 0.4, 1.5))
cam = bpy.context.object
cam.name = "View"
cam.data.lens = 24.0
cam.parent = building
bpy.context.view_layer.update()
target = building.matrix_world @ __import__("mathutils").Vector((2.0, 2.0, 1.0))
cam_world = cam.matrix_world.translation.copy()
cam.parent = None
cam.location = cam_world
cam.rotation_euler = (target - cam_world).to_track_quat("-Z", "Y").to_euler()
scene = bpy.context.scene
scene.camera = cam
scene.render.resolution_x, scene.render.resolution_y = 1920, 1080
bpy.context.view_layer.update()

bpy.ops.export_scene.gltf(filepath=os.path.join(out, "studio.glb"), export_format="GLB", export_cameras=True)
bpy.ops.wm.obj_export(filepath=os.path.join(out, "studio.obj"))
print("wrote", os.path.join(out, "studio.glb"), os.path.join(out, "studio.obj"))
