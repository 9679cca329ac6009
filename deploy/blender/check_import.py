# Imports a sirad .glb (or .ply) into Blender (headless) and checks what Blender sees: every
# expected object (a .ply is one object, named after the file), with the solved colours as a
# colour attribute on its vertices, not all black.
#   blender -b --factory-startup --python deploy/blender/check_import.py -- FILE.glb NAME [NAME ...]
#   blender -b --factory-startup --python deploy/blender/check_import.py -- FILE.ply
import os
import sys
import bpy

args = sys.argv[sys.argv.index("--") + 1:]
path, names = args[0], args[1:]
bpy.ops.object.select_all(action="SELECT")
bpy.ops.object.delete()
# import_shading: the default "NORMALS" fails in Debian 12's Blender 3.4 with its numpy 1.24
# (np.bool); "SMOOTH" takes the other path and loses nothing here (the file has no normals).
if path.endswith(".ply"):
    bpy.ops.import_mesh.ply(filepath=path)
    names = names or [os.path.splitext(os.path.basename(path))[0]]
else:
    bpy.ops.import_scene.gltf(filepath=path, import_shading="SMOOTH")
found = {o.name: o for o in bpy.data.objects if o.type == "MESH"}
bad = []
for name in names:
    obj = found.get(name)
    if obj is None:
        bad.append(f"no object {name} (objects: {sorted(found)})")
        continue
    mesh = obj.data
    attrs = [a for a in mesh.color_attributes] if hasattr(mesh, "color_attributes") else []
    if not attrs:
        bad.append(f"{name}: no colour attribute")
        continue
    brightest = max(max(c.color[0], c.color[1], c.color[2]) for c in attrs[0].data)
    print(f"{name}: {len(mesh.vertices)} vertices, colour attribute '{attrs[0].name}', brightest {brightest:.3f}")
    if brightest <= 0.0:
        bad.append(f"{name}: every vertex colour is black")
if bad:
    print("ROUND TRIP FAILED: " + "; ".join(bad))
    sys.exit(1)
print("ROUND TRIP OK")
