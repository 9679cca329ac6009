# The corpus apartment (tests/data/blender/make_apartment.py) with its slabs and walls cut where
# the walls meet them (bmesh bisect along every wall's faces: x 0, 4.95, 5.05, 8 and y 0, 3.5, 4,
# 6), then exported as that script does. The geometry is the same (Cycles renders it alike);
# only no face of a slab or an outer wall spans the foot of a wall any more, so no patch of
# sirad's mesh straddles one: a measurement of what straddling patches cost (bench/RESULTS.md,
# "The Blender corpus: what is left of the image's bias near the lamp").
#   blender -b --factory-startup --python bench/scenes/make_apartment_bisected.py -- OUTDIR
import os
import sys

import bmesh
import bpy
from mathutils import Vector

here = os.path.dirname(os.path.abspath(__file__))
corpus = os.path.join(here, "..", "..", "tests", "data", "blender")
source = os.path.join(corpus, "make_apartment.py")
out = sys.argv[sys.argv.index("--") + 1]


def bisect_at_walls():
    planes = [((x, 0, 0), (1, 0, 0)) for x in (0.0, 4.95, 5.05, 8.0)] + [((0, y, 0), (0, 1, 0)) for y in (0.0, 3.5, 4.0, 6.0)]
    for name in ("Floor", "CeilingSlab", "WallSouth", "WallNorth", "WallWest", "WallEast", "WallInner"):
        o = bpy.data.objects[name]
        to_world = o.matrix_world.copy()
        bm = bmesh.new()
        bm.from_mesh(o.data)
        bm.transform(to_world)
        for co, no in planes:
            bmesh.ops.bisect_plane(bm, geom=bm.verts[:] + bm.edges[:] + bm.faces[:], plane_co=Vector(co), plane_no=Vector(no), dist=1e-6)
        bm.transform(to_world.inverted())
        bm.to_mesh(o.data)
        bm.free()


code = open(source).read().replace("bpy.ops.export_scene.gltf(", "BISECT_AT_WALLS()\nbpy.ops.export_scene.gltf(", 1)
code = code.replace("os.path.dirname(os.path.abspath(__file__))", repr(os.path.abspath(corpus)), 1)
sys.argv = [source, "--", out]
exec(compile(code, source, "exec"), {"__name__": "__main__", "BISECT_AT_WALLS": bisect_at_walls})
