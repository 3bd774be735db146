"""glint fallback fix: a Blender add-on that makes an imported glint glTF render the BRDF glint fitted.

Blender's glTF importer builds one Principled BSDF from the file's pbrMetallicRoughness and
KHR_materials_* values, but leaves its distribution on multiple-scattering GGX. The glTF BRDF, which
glint fits the fallback against, is single-scattering: multiple scattering adds 8.6 % of energy at
roughness 0.54 and 32.5 % at roughness 1 (measured with Cycles). This add-on switches the Principled
BSDF of every material that carries glint's extras (the `glint` custom property the importer makes
from `material.extras.glint`) to single-scattering GGX, and leaves every other material alone.

Install: Edit > Preferences > Add-ons > Install from Disk, pick this folder zipped (or copy the folder
into Blender's `scripts/addons`), enable "glint fallback fix". It adds Object > glint: Fix Imported
Materials, and it runs by itself after every glTF import. From Python: `glint_blender.fix_materials()`.
"""

bl_info = {
    "name": "glint fallback fix",
    "author": "glint",
    "version": (1, 0, 0),
    "blender": (4, 2, 0),
    "location": "Object > glint: Fix Imported Materials (and after every glTF import)",
    "description": "Single-scattering GGX on the Principled BSDF of materials exported by glint",
    "category": "Import-Export",
}

import bpy


def is_glint_material(material):
    """Whether `material` came from a glint glTF (its extras carry the lobe table)."""
    return material is not None and "glint" in material.keys()


def fix_material(material):
    """Sets single-scattering GGX on the material's Principled BSDF nodes. Returns how many changed."""
    if not is_glint_material(material) or not material.use_nodes:
        return 0
    changed = 0
    for node in material.node_tree.nodes:
        if node.type == "BSDF_PRINCIPLED" and node.distribution != "GGX":
            node.distribution = "GGX"
            changed += 1
    return changed


def fix_materials(materials=None):
    """Fixes every glint material (all of `bpy.data.materials` by default). Returns the count."""
    return sum(fix_material(m) for m in (materials if materials is not None else bpy.data.materials))


class GLINT_OT_fix_materials(bpy.types.Operator):
    """Single-scattering GGX on the Principled BSDF of every material glint exported"""

    bl_idname = "glint.fix_materials"
    bl_label = "glint: Fix Imported Materials"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        n = fix_materials()
        self.report({"INFO"}, f"glint: {n} Principled BSDF node(s) set to single-scattering GGX")
        return {"FINISHED"}


def _menu(self, context):
    self.layout.operator(GLINT_OT_fix_materials.bl_idname)


class glTF2ImportUserExtension:
    """Hook the glTF importer calls after it builds the scene (Blender 4.x/5.x importer API)."""

    def gather_import_scene_after_nodes_hook(self, gltf_scene, blender_scene, import_settings):
        fix_materials()


def register():
    bpy.utils.register_class(GLINT_OT_fix_materials)
    bpy.types.VIEW3D_MT_object.append(_menu)


def unregister():
    bpy.types.VIEW3D_MT_object.remove(_menu)
    bpy.utils.unregister_class(GLINT_OT_fix_materials)
