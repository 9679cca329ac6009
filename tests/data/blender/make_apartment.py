# Builds the apartment of the Blender corpus (issue 34), headless, the way an architect models:
#   blender -b --factory-startup --python tests/data/blender/make_apartment.py -- OUTDIR
# writes OUTDIR/apartment.glb (Blender's glTF exporter, its defaults and the camera) and
# OUTDIR/apartment.obj + .mtl (Blender's OBJ exporter, its defaults: n-gons, no triangulation).
#
# Four rooms on an 8 x 6 m plan, 2.6 m high (Blender is Z-up; both exporters write Y-up):
#   living  x 0..5, y 0..4   a window in the outer wall, a sky plane behind it, a ceiling panel
#                            1.5 cm below the ceiling (a plane), a table on a turned empty, a sofa
#   hall    x 0..5, y 4..6   no lamp: lit only through the doorway from the living room
#   bedroom x 5..8, y 0..3.5 a ceiling lamp that is a thin box 1 cm below the ceiling, a bed, a
#                            wardrobe that has no material
#   bath    x 5..8, y 3.5..6 a small panel 2 cm below the ceiling, a tub
# Outer walls are 20 cm boxes, the living/bedroom wall a 10 cm box, their doors and the window cut
# by Boolean modifiers (applied, so both exporters write the cut faces: concave n-gons). The
# living/hall wall is two zero-thickness planes at one place, white towards the living room and
# blue towards the hall; the bedroom/bath wall is one zero-thickness plane. Every material is
# Blender's default two-sided one, so the glTF says doubleSided; emitters are Principled BSDF
# emission, which Cycles emits from both sides.
import math
import os
import sys

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from blender_scene import box, clear_scene, cut, material, plane_wall, shell  # noqa: E402

out = sys.argv[sys.argv.index("--") + 1] if "--" in sys.argv else os.getcwd()
clear_scene()

H = 2.6  # storey height (floor top to ceiling underside)

plaster = material("Plaster", (0.8, 0.8, 0.78))
ceiling_white = material("Ceiling", (0.85, 0.85, 0.85))
wood = material("Oak", (0.45, 0.3, 0.18))
blue = material("BluePaint", (0.15, 0.25, 0.6))
fabric = material("Sofa", (0.6, 0.15, 0.12))
linen = material("Linen", (0.75, 0.72, 0.65))
tiles = material("Tiles", (0.55, 0.65, 0.7))
lamp_white = material("LampWhite", (0.8, 0.8, 0.8), (1.0, 0.97, 0.92), 8.0)
lamp_warm = material("LampWarm", (0.8, 0.8, 0.8), (1.0, 0.85, 0.65), 8.0)
sky = material("Sky", (0.0, 0.0, 0.0), (0.55, 0.7, 1.0), 2.0)


def panel(name, mat, cx, cy, sx, sy, z):
    """A rectangular plane lamp facing down at height z."""
    bpy.ops.mesh.primitive_plane_add(size=1.0, location=(cx, cy, z))
    o = bpy.context.object
    o.name = name
    o.scale = (sx, sy, 1.0)
    o.rotation_euler = (math.pi, 0.0, 0.0)
    o.data.materials.append(mat)
    return o


# Slabs and outer walls (20 cm).
south = shell(8.0, 6.0, H, 0.2, wood, ceiling_white, plaster)
cut(south, "Window", 1.5, -0.3, 0.9, 3.5, 0.1, 2.1)

# The living/bedroom wall (10 cm) with two doors: living -> bedroom and hall -> bath.
inner = box("WallInner", plaster, 4.95, 0.0, 0.0, 5.05, 6.0, H)
cut(inner, "DoorBedroom", 4.9, 1.0, -0.1, 5.1, 1.9, 2.1)
cut(inner, "DoorBath", 4.9, 4.6, -0.1, 5.1, 5.4, 2.1)

# Living/hall: zero-thickness, a door at x 3.0..3.9; white faces the living room (-y), blue the hall.
y = 4.0
hall_wall = [(0, y, 0), (3.0, y, 0), (3.0, y, 2.1), (0, y, 2.1), (0, y, H), (3.0, y, H),
             (3.9, y, 0), (4.95, y, 0), (4.95, y, 2.1), (3.9, y, 2.1), (3.9, y, H), (4.95, y, H)]
hall_quads = [(0, 1, 2, 3), (3, 2, 5, 4), (2, 9, 10, 5), (6, 7, 8, 9), (9, 8, 11, 10)]
plane_wall("PartitionLiving", plaster, hall_wall, hall_quads)            # normal -y
plane_wall("PartitionHall", blue, hall_wall, hall_quads, flip=True)      # normal +y
# Bedroom/bath: one zero-thickness plane, no door.
y = 3.5
plane_wall("PartitionBath", tiles, [(5.05, y, 0), (8.0, y, 0), (8.0, y, H), (5.05, y, H)], [(0, 1, 2, 3)])

# Lamps just under the ceiling, and the sky behind the window.
panel("LampLiving", lamp_white, 2.5, 2.0, 1.2, 0.6, H - 0.015)
box("LampBedroom", lamp_warm, 6.2, 1.45, H - 0.04, 6.8, 2.05, H - 0.01)
panel("LampBath", lamp_white, 6.5, 4.75, 0.4, 0.4, H - 0.02)
bpy.ops.mesh.primitive_plane_add(size=1.0, location=(2.5, -2.5, 1.5))
sky_plane = bpy.context.object
sky_plane.name = "Sky"
sky_plane.scale = (8.0, 4.0, 1.0)
sky_plane.rotation_euler = (-math.pi / 2, 0.0, 0.0)  # normal +y, towards the window
sky_plane.data.materials.append(sky)

# Furniture: a table on a turned empty (a transform hierarchy), a sofa, a bed, a wardrobe whose one
# material slot is empty (glTF: no material; OBJ: `usemtl` with no name), a tub.
bpy.ops.object.empty_add(location=(2.2, 1.7, 0.0))
pivot = bpy.context.object
pivot.name = "TablePivot"
pivot.rotation_euler = (0.0, 0.0, math.radians(20.0))
parts = [box("TableTop", wood, -0.7, -0.4, 0.72, 0.7, 0.4, 0.76)]
for sx in (-1, 1):
    for sy in (-1, 1):
        parts.append(box(f"TableLeg{len(parts)}", wood, sx * 0.62 - 0.03, sy * 0.32 - 0.03, 0.0,
                         sx * 0.62 + 0.03, sy * 0.32 + 0.03, 0.72))
for p in parts:
    p.parent = pivot
sofa = box("SofaSeat", fabric, 1.4, 3.1, 0.0, 3.4, 3.9, 0.45)
back = box("SofaBack", fabric, 1.4, 3.75, 0.45, 3.4, 3.95, 0.85)
back.parent = sofa
sofa.rotation_euler = (0.0, 0.0, math.radians(-4.0))
box("Bed", linen, 5.6, 0.2, 0.0, 7.2, 2.2, 0.5)
wardrobe = box("Wardrobe", None, 7.35, 0.3, 0.0, 7.95, 1.5, 2.0)
wardrobe.data.materials.append(None)  # an empty slot, as a deleted material leaves
box("Tub", tiles, 7.2, 4.0, 0.0, 7.9, 5.6, 0.55)

# The camera: 18 mm on the default 36 mm sensor, 3:2, in the living room's corner.
bpy.ops.object.camera_add(location=(0.35, 0.35, 1.6))
cam = bpy.context.object
cam.name = "View"
cam.data.lens = 18.0
target = bpy.data.objects["SofaSeat"].matrix_world.translation.copy()
target.z = 1.0
cam.rotation_euler = (target - cam.location).to_track_quat("-Z", "Y").to_euler()
scene = bpy.context.scene
scene.camera = cam
scene.render.resolution_x, scene.render.resolution_y = 1536, 1024
bpy.context.view_layer.update()

bpy.ops.export_scene.gltf(filepath=os.path.join(out, "apartment.glb"), export_format="GLB", export_cameras=True)
bpy.ops.wm.obj_export(filepath=os.path.join(out, "apartment.obj"))
print("wrote", os.path.join(out, "apartment.glb"), os.path.join(out, "apartment.obj"))
