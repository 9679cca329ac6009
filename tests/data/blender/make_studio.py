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

import bmesh
import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from blender_scene import clear_scene, material  # noqa: E402

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


def adopt(o):
    o.parent = building
    return o


def box(name, mat, x0, y0, z0, x1, y1, z1):
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=((x0 + x1) / 2, (y0 + y1) / 2, (z0 + z1) / 2))
    o = bpy.context.object
    o.name = name
    o.scale = (x1 - x0, y1 - y0, z1 - z0)
    bpy.ops.object.transform_apply(location=False, rotation=False, scale=True)
    if mat is not None:
        o.data.materials.append(mat)
    return adopt(o)


def cut(wall, name, x0, y0, z0, x1, y1, z1):
    """A door or window cut by a Boolean difference (the cutter in the wall's own frame), applied."""
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=((x0 + x1) / 2, (y0 + y1) / 2, (z0 + z1) / 2))
    cutter = bpy.context.object
    cutter.scale = (x1 - x0, y1 - y0, z1 - z0)
    cutter.parent = building
    bpy.context.view_layer.update()
    bpy.context.view_layer.objects.active = wall
    mod = wall.modifiers.new(name, "BOOLEAN")
    mod.operation = "DIFFERENCE"
    mod.object = cutter
    bpy.ops.object.modifier_apply(modifier=mod.name)
    bpy.data.objects.remove(cutter, do_unlink=True)


def plane(name, mat, points, flip=False):
    mesh = bpy.data.meshes.new(name)
    bm = bmesh.new()
    verts = [bm.verts.new(p) for p in points]
    bm.faces.new(list(reversed(verts)) if flip else verts)
    bm.to_mesh(mesh)
    bm.free()
    o = bpy.data.objects.new(name, mesh)
    bpy.context.collection.objects.link(o)
    o.data.materials.append(mat)
    return adopt(o)


box("Floor", floor_wood, -0.15, -0.15, -0.2, 6.15, 4.15, 0.0)
box("CeilingSlab", ceiling_white, -0.15, -0.15, H, 6.15, 4.15, H + 0.2)
south = box("WallSouth", plaster, -0.15, -0.15, 0.0, 6.15, 0.0, H)
box("WallNorth", plaster, -0.15, 4.0, 0.0, 6.15, 4.15, H)
box("WallWest", plaster, -0.15, 0.0, 0.0, 0.0, 4.0, H)
box("WallEast", plaster, 6.0, 0.0, 0.0, 6.15, 4.0, H)
cut(south, "Window", 1.0, -0.25, 0.8, 3.0, 0.1, 2.2)
closet_x = box("ClosetWallX", plaster, 4.45, 2.45, 0.0, 4.55, 4.0, H)
box("ClosetWallY", plaster, 4.55, 2.45, 0.0, 6.0, 2.55, H)
cut(closet_x, "ClosetDoor", 4.4, 3.0, -0.1, 4.6, 3.8, 2.05)

# The divider: two coincident planes, red facing the window (-y), white facing the bed (+y).
pts = [(1.0, 2.0, 0.0), (3.0, 2.0, 0.0), (3.0, 2.0, 1.4), (1.0, 2.0, 1.4)]
plane("DividerRed", red, pts)              # normal -y (counter-clockwise seen from -y)
plane("DividerWhite", white, pts, flip=True)

# The round lamp: lid 1 cm under the ceiling.
bpy.ops.mesh.primitive_cylinder_add(vertices=32, radius=0.3, depth=0.03, location=(2.0, 1.2, H - 0.01 - 0.015))
disc = bpy.context.object
disc.name = "LampDisc"
disc.data.materials.append(lamp)
adopt(disc)

box("Bed", linen, 1.2, 2.6, 0.0, 3.2, 3.9, 0.45)

bpy.ops.mesh.primitive_plane_add(size=1.0, location=(2.0, -2.0, 1.5))
sky_plane = bpy.context.object
sky_plane.name = "Sky"
sky_plane.scale = (6.0, 3.5, 1.0)
sky_plane.rotation_euler = (-math.pi / 2, 0.0, 0.0)  # normal +y, towards the window
sky_plane.data.materials.append(sky)
adopt(sky_plane)

# The camera: 24 mm, 16:9, by the east wall looking back at the divider and the window.
bpy.ops.object.camera_add(location=(5.6, 0.4, 1.5))
cam = bpy.context.object
cam.name = "View"
cam.data.lens = 24.0
adopt(cam)
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
