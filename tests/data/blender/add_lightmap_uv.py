# Builds tests/data/blender/apartment-uv2.glb with Blender, headless: the apartment as exported
# (apartment.glb) imported, a second UV map "Lightmap" added to every mesh and laid out by
# Lightmap Pack over all of them in one atlas (UV > Lightmap Pack, as a user makes a lightmap
# UV set), exported with the glTF exporter's defaults (the second UV map is TEXCOORD_1):
#   blender -b --factory-startup --python tests/data/blender/add_lightmap_uv.py -- IN.glb OUT.glb
# (Debian's Blender imports glTF with flat shading: its smooth-normal path needs a newer numpy.)
import sys, bpy
args = sys.argv[sys.argv.index("--") + 1:]
src, dst = args[0], args[1]
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.import_scene.gltf(filepath=src, import_shading='FLAT')
meshes = [o for o in bpy.context.scene.objects if o.type == 'MESH']
for o in meshes:
    if len(o.data.uv_layers) == 0:
        o.data.uv_layers.new(name="UVMap")
    o.data.uv_layers.new(name="Lightmap")
    o.data.uv_layers.active = o.data.uv_layers["Lightmap"]
bpy.ops.object.select_all(action='DESELECT')
for o in meshes: o.select_set(True)
bpy.context.view_layer.objects.active = meshes[0]
bpy.ops.object.mode_set(mode='EDIT')
bpy.ops.mesh.select_all(action='SELECT')
bpy.ops.uv.lightmap_pack(PREF_CONTEXT='ALL_FACES', PREF_PACK_IN_ONE=True, PREF_NEW_UVLAYER=False, PREF_BOX_DIV=12, PREF_MARGIN_DIV=0.2)
bpy.ops.object.mode_set(mode='OBJECT')
bpy.ops.export_scene.gltf(filepath=dst)
print("meshes", len(meshes))
