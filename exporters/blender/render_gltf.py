"""Renders a glint-exported glTF in Blender (Cycles, CPU) as `glint render --reference` renders it,
and compares the two pictures.

Run with the Python that has PyPI's `bpy` (5.0.1 for Python 3.11):

    python render_gltf.py --glb fit.glb --env studio_1k.exr --reference ref.exr --out blender.exr
        [--rotation-deg 0] [--spp 256] [--fix] [--usda fit.usda] [--also other.exr]
        [--report report.json]

The conventions it matches (docs/fallback.md, measured with a Lambertian material first):
- the environment: an Environment Texture read "Closest" (constant per texel, as glint's reference
  reads it), turned by -90° - rotation about Blender's +Z (glint's u = 0.5 + atan2(x, -z)/2π in
  glTF's Y-up frame; the importer maps glTF +Y to Blender +Z);
- the camera: the one the .glb carries (glint's view), vertical field of view kept, image W × H
  of the reference;
- direct light only (max bounces 0, MIS), Gaussian pixel filter 0.01 px (rays through pixel
  centres), shadow-terminator geometry offset 1 (shadow rays from the smooth surface), no denoiser,
  no adaptive sampling, Standard view transform, float EXR;
- `--fix` applies the glint add-on (single-scattering GGX) before rendering.

The report (JSON on stdout, and in --report): the Principled BSDF inputs the importer set, the
relative RMSE against the reference over pixels both cover (alpha = 1 in both), the pixel count,
the same against each --also image (`glint render --fallback` of the .glb: how exactly Cycles
renders the glTF BRDF glint evaluates), and what Blender built from the .usda when --usda is given.
"""

import argparse
import json
import math
import os
import sys

import bpy


def principled_inputs(material):
    out = {"distribution": None}
    if not material or not material.use_nodes:
        return out
    for node in material.node_tree.nodes:
        if node.type == "BSDF_PRINCIPLED":
            out["distribution"] = node.distribution
            for name in ["Base Color", "Metallic", "Roughness", "IOR", "Specular IOR Level", "Specular Tint",
                         "Coat Weight", "Coat Roughness", "Coat IOR", "Sheen Weight", "Sheen Tint",
                         "Sheen Roughness", "Anisotropic", "Anisotropic Rotation"]:
                s = node.inputs.get(name)
                if s is None:
                    continue
                linked = s.is_linked
                v = s.default_value
                out[name] = {"value": [float(x) for x in v] if hasattr(v, "__len__") else float(v), "linked": linked}
            return out
    return out


def setup_world(env_path, rotation_deg):
    world = bpy.data.worlds.new("glint_env")
    bpy.context.scene.world = world
    world.use_nodes = True
    nt = world.node_tree
    nt.nodes.clear()
    coord = nt.nodes.new("ShaderNodeTexCoord")
    mapping = nt.nodes.new("ShaderNodeMapping")
    mapping.vector_type = "POINT"
    mapping.inputs["Rotation"].default_value = (0.0, 0.0, -0.5 * math.pi - math.radians(rotation_deg))
    tex = nt.nodes.new("ShaderNodeTexEnvironment")
    tex.image = bpy.data.images.load(os.path.abspath(env_path))
    tex.image.colorspace_settings.name = "Non-Color"
    tex.interpolation = "Closest"
    tex.projection = "EQUIRECTANGULAR"
    bg = nt.nodes.new("ShaderNodeBackground")
    out = nt.nodes.new("ShaderNodeOutputWorld")
    nt.links.new(coord.outputs["Generated"], mapping.inputs["Vector"])
    nt.links.new(mapping.outputs["Vector"], tex.inputs["Vector"])
    nt.links.new(tex.outputs["Color"], bg.inputs["Color"])
    nt.links.new(bg.outputs["Background"], out.inputs["Surface"])


def setup_render(width, height, spp, out_path):
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    c = scene.cycles
    c.device = "CPU"
    c.samples = spp
    c.use_adaptive_sampling = False
    c.use_denoising = False
    c.max_bounces = 0
    c.seed = 1
    c.sample_clamp_direct = 0.0
    c.sample_clamp_indirect = 0.0
    c.pixel_filter_type = "GAUSSIAN"
    c.filter_width = 0.01
    scene.render.film_transparent = True
    scene.render.resolution_x = width
    scene.render.resolution_y = height
    scene.render.resolution_percentage = 100
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    scene.render.image_settings.color_mode = "RGBA"
    scene.render.filepath = os.path.abspath(out_path)
    for obj in scene.objects:
        if obj.type == "MESH":
            if hasattr(obj, "shadow_terminator_geometry_offset"):
                obj.shadow_terminator_geometry_offset = 1.0
            elif hasattr(obj, "cycles") and hasattr(obj.cycles, "shadow_terminator_geometry_offset"):
                obj.cycles.shadow_terminator_geometry_offset = 1.0


def load_rgba(path):
    img = bpy.data.images.load(os.path.abspath(path), check_existing=False)
    img.colorspace_settings.name = "Non-Color"
    w, h = img.size
    px = list(img.pixels[:])
    bpy.data.images.remove(img)
    return w, h, px


def compare(reference, rendered):
    wr, hr, a = load_rgba(reference)
    wb, hb, b = load_rgba(rendered)
    if (wr, hr) != (wb, hb):
        raise SystemExit(f"error: reference is {wr}x{hr}, Blender's render {wb}x{hb}")
    num = den = 0.0
    n = 0
    for k in range(wr * hr):
        if a[4 * k + 3] >= 0.999 and b[4 * k + 3] >= 0.999:
            for c in range(3):
                num += (b[4 * k + c] - a[4 * k + c]) ** 2
                den += a[4 * k + c] ** 2
            n += 1
    return (math.sqrt(num / den) if den > 0 else float("nan")), n


def glb_yfov(path):
    """The first camera's yfov from the GLB's JSON chunk."""
    with open(path, "rb") as f:
        data = f.read()
    length = int.from_bytes(data[12:16], "little")
    gltf = json.loads(data[20:20 + length])
    return float(gltf["cameras"][0]["perspective"]["yfov"])


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--glb", required=True)
    ap.add_argument("--env", required=True)
    ap.add_argument("--reference", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--rotation-deg", type=float, default=0.0)
    ap.add_argument("--spp", type=int, default=256)
    ap.add_argument("--fix", action="store_true")
    ap.add_argument("--also", action="append", default=[],
                    help="another image to compare Blender's render with (e.g. glint's render of the fallback)")
    ap.add_argument("--usda")
    ap.add_argument("--report")
    args = ap.parse_args()

    report = {}
    if args.usda:
        bpy.ops.wm.read_factory_settings(use_empty=True)
        bpy.ops.wm.usd_import(filepath=os.path.abspath(args.usda))
        report["usda"] = {m.name: principled_inputs(m) for m in bpy.data.materials}

    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_scene.gltf(filepath=os.path.abspath(args.glb))
    materials = [m for m in bpy.data.materials if "glint" in m.keys()]
    if not materials:
        raise SystemExit("error: no material with glint extras was imported")
    report["imported"] = {m.name: principled_inputs(m) for m in materials}
    if args.fix:
        sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
        import glint_blender

        report["fixed_nodes"] = glint_blender.fix_materials()
    cams = [o for o in bpy.context.scene.objects if o.type == "CAMERA"]
    if not cams:
        raise SystemExit("error: the .glb carries no camera (export it with --bake or --scene)")
    bpy.context.scene.camera = cams[0]
    wr, hr, _ = load_rgba(args.reference)
    cam = cams[0].data
    cam.sensor_fit = "VERTICAL"
    cam.angle_y = glb_yfov(args.glb)
    setup_world(args.env, args.rotation_deg)
    setup_render(wr, hr, args.spp, args.out)
    bpy.ops.render.render(write_still=True)
    rmse, n = compare(args.reference, args.out)
    report["also"] = {p: compare(p, args.out)[0] for p in args.also}
    report.update({"relative_rmse": rmse, "pixels": n, "spp": args.spp, "fix": args.fix,
                   "camera_yfov_deg": math.degrees(cam.angle_y)})
    text = json.dumps(report, indent=1, sort_keys=True)
    if args.report:
        with open(args.report, "w") as f:
            f.write(text)
    print("GLINT_REPORT " + json.dumps(report, sort_keys=True))


if __name__ == "__main__":
    main()
