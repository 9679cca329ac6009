# What the scripts that build tests/data/blender's scenes in Blender share (make_room.py,
# make_apartment.py, make_studio.py): an empty scene to start from, a diffuse Principled material,
# optionally emitting, as a Blender user sets one up, and the ways an architect builds: boxes,
# doors and windows cut by applied Booleans, zero-thickness walls, a building's shell. `parent`,
# where given, is the object the new one hangs from: its coordinates are then in that frame.
import bmesh
import bpy


def clear_scene():
    bpy.ops.object.select_all(action="SELECT")
    bpy.ops.object.delete()
    for block in (bpy.data.meshes, bpy.data.materials, bpy.data.cameras, bpy.data.lights):
        for item in list(block):
            block.remove(item)


def material(name, colour, emission=None, strength=0.0):
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    bsdf = m.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (*colour, 1.0)
    bsdf.inputs["Roughness"].default_value = 1.0
    bsdf.inputs["Specular"].default_value = 0.0
    if emission is not None:
        bsdf.inputs["Emission"].default_value = (*emission, 1.0)
        bsdf.inputs["Emission Strength"].default_value = strength
    return m


def box(name, mat, x0, y0, z0, x1, y1, z1, parent=None):
    """An axis-aligned box as the default cube moved and scaled (the scale applied)."""
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=((x0 + x1) / 2, (y0 + y1) / 2, (z0 + z1) / 2))
    o = bpy.context.object
    o.name = name
    o.scale = (x1 - x0, y1 - y0, z1 - z0)
    bpy.ops.object.transform_apply(location=False, rotation=False, scale=True)
    if mat is not None:
        o.data.materials.append(mat)
    o.parent = parent
    return o


def cut(wall, name, x0, y0, z0, x1, y1, z1, parent=None):
    """A door or window cut by a Boolean difference, applied as an architect does before export.
    The faces the cut makes take the wall's material or, in some of Blender 3.4's runs and not
    in others, an empty slot (the cutter has none): the exports' geometry is the same every run,
    which of the cut faces say `usemtl` with no name is not."""
    cutter = box(name, None, x0, y0, z0, x1, y1, z1, parent)
    cutter.display_type = "WIRE"
    bpy.context.view_layer.update()
    bpy.context.view_layer.objects.active = wall
    mod = wall.modifiers.new(name, "BOOLEAN")
    mod.operation = "DIFFERENCE"
    mod.object = cutter
    bpy.ops.object.modifier_apply(modifier=mod.name)
    bpy.data.objects.remove(cutter, do_unlink=True)


def plane_wall(name, mat, points, faces, flip=False, parent=None):
    """A zero-thickness wall: one mesh of polygons (vertex index lists) through `points` (x, y, z)."""
    mesh = bpy.data.meshes.new(name)
    bm = bmesh.new()
    verts = [bm.verts.new(p) for p in points]
    for f in faces:
        bm.faces.new([verts[i] for i in (reversed(f) if flip else f)])
    bm.to_mesh(mesh)
    bm.free()
    o = bpy.data.objects.new(name, mesh)
    bpy.context.collection.objects.link(o)
    o.data.materials.append(mat)
    o.parent = parent
    return o


def shell(width, depth, height, wall, floor_mat, ceiling_mat, wall_mat, parent=None):
    """The floor and ceiling slabs (20 cm) and four outer walls `wall` thick around the rooms
    x 0..width, y 0..depth, z 0..height. Returns the south wall (y < 0), where the window goes."""
    box("Floor", floor_mat, -wall, -wall, -0.2, width + wall, depth + wall, 0.0, parent)
    box("CeilingSlab", ceiling_mat, -wall, -wall, height, width + wall, depth + wall, height + 0.2, parent)
    south = box("WallSouth", wall_mat, -wall, -wall, 0.0, width + wall, 0.0, height, parent)
    box("WallNorth", wall_mat, -wall, depth, 0.0, width + wall, depth + wall, height, parent)
    box("WallWest", wall_mat, -wall, 0.0, 0.0, 0.0, depth, height, parent)
    box("WallEast", wall_mat, width, 0.0, 0.0, width + wall, depth, height, parent)
    return south
