#!/usr/bin/env python3
"""Checks a glint USD export with usd-core (an independent reader).

usage: check_usd.py STAGE.usda MATERIAL.json

Opens the stage, validates it — stage metadata (defaultPrim, upAxis Y, metersPerUnit), the UsdShade
wiring (ConnectableAPI, the Material's surface output resolving to a UsdPreviewSurface, the "glint"
render-context output resolving to the glint_dbrdf_srbf shader), MaterialBindingAPI on a bound gprim,
the table asset resolving beside the stage, UsdUtils.ComplianceChecker (when this usd-core has it) and
the UsdValidation validators (when it has them) without errors — and compares every number of the lobe
table (lambda, sigma, f0, rho_d, centres, coefficients; plus the fallback when the JSON has one) with
glint's material JSON within float precision (relative 1e-6). The fallback's anisotropy, when the
JSON's "fallback" has an "anisotropy" key ([strength, rotation] or null), is compared with the
Material's customData glint.fallback_anisotropy (or its absence).

Prints "check_usd: OK ..." and exits 0, or prints one line "check_usd: FAIL: <reason>" and exits 1.
"""

import json
import math
import os
import sys
import warnings

REL = 1e-6
ABS = 1e-30  # f32 flushes values below ~1e-38 to zero; anything that small is zero for a BRDF


def fail(msg):
    print("check_usd: FAIL: " + " ".join(str(msg).split()))
    sys.exit(1)


def close(a, b):
    a, b = float(a), float(b)
    return math.isfinite(a) and abs(a - b) <= REL * max(abs(a), abs(b)) + ABS


def compare(label, got, want):
    got = list(got)
    want = list(want)
    if len(got) != len(want):
        fail(f"{label}: the stage has {len(got)} values, the material JSON {len(want)}")
    for i, (g, w) in enumerate(zip(got, want)):
        if not close(g, w):
            fail(f"{label}[{i}]: stage {g!r} vs material JSON {w!r} (relative tolerance {REL})")


def mtlx_surface_shaders(material):
    """The shaders the Material's `mtlx` render context connects (none when it has no such output)."""
    from pxr import UsdShade

    out = material.GetSurfaceOutput("mtlx")
    if not out or not out.HasConnectedSource():
        return []
    source = out.GetConnectedSource()[0]
    return [UsdShade.Shader(source.GetPrim())]


def check_mtlx_shader(shader):
    """Checks a MaterialX shader prim against MaterialX's own node definition."""
    import MaterialX as mx

    node_id = shader.GetIdAttr().Get()
    lib = mx.createDocument()
    mx.loadLibraries(mx.getDefaultDataLibraryFolders(), mx.getDefaultDataSearchPath(), lib)
    nodedef = lib.getNodeDef(node_id)
    if nodedef is None:
        fail(f"{shader.GetPath()}: MaterialX has no node definition {node_id}")
    types = {i.getName(): i.getType() for i in nodedef.getActiveInputs()}
    usd_type = {"float": "float", "color3": "color3f", "vector3": "float3", "boolean": "bool", "integer": "int"}
    for inp in shader.GetInputs():
        name = inp.GetBaseName()
        if name not in types:
            fail(f"{shader.GetPath()}: input {name} is not an input of {node_id}")
        want = usd_type.get(types[name])
        got = str(inp.GetTypeName())
        if want != got:
            fail(f"{shader.GetPath()}: input {name} is {got}, {node_id} wants {types[name]} ({want})")
    if not shader.GetOutput("out"):
        fail(f"{shader.GetPath()}: no outputs:out")


def flat(rows):
    return [float(x) for row in rows for x in row]


def main():
    if len(sys.argv) != 3:
        fail("usage: check_usd.py STAGE.usda MATERIAL.json")
    stage_path, json_path = sys.argv[1], sys.argv[2]
    try:
        from pxr import Sdf, Sdr, Tf, Usd, UsdGeom, UsdShade, UsdUtils
    except ImportError as e:
        fail(f"usd-core is not importable ({e}); pip install usd-core")
    try:
        with open(json_path, encoding="utf-8") as f:
            mat_json = json.load(f)
    except (OSError, ValueError) as e:
        fail(f"cannot read {json_path}: {e}")

    try:
        stage = Usd.Stage.Open(stage_path)
    except Tf.ErrorException as e:
        fail(f"usd-core cannot open {stage_path}: {e}")
    if not stage:
        fail(f"usd-core cannot open {stage_path}")

    # Stage metadata.
    if UsdGeom.GetStageUpAxis(stage) != UsdGeom.Tokens.y:
        fail(f"upAxis is {UsdGeom.GetStageUpAxis(stage)}, not Y")
    if not stage.HasAuthoredMetadata("metersPerUnit"):
        fail("metersPerUnit is not authored")
    if not stage.GetDefaultPrim():
        fail("no defaultPrim")

    # Exactly one material; its surface outputs.
    materials = [UsdShade.Material(p) for p in stage.Traverse() if p.IsA(UsdShade.Material)]
    if len(materials) != 1:
        fail(f"expected one Material, found {len(materials)}")
    material = materials[0]
    if not UsdShade.ConnectableAPI(material.GetPrim()).IsContainer():
        fail("the Material is not a connectable container")
    preview, _, _ = material.ComputeSurfaceSource()
    if not preview or preview.GetIdAttr().Get() != "UsdPreviewSurface":
        fail("the Material's outputs:surface does not resolve to a UsdPreviewSurface shader")
    glint, _, _ = material.ComputeSurfaceSource("glint")
    if not glint or glint.GetInput("model").Get() != "dbrdf-srbf":
        fail("the Material's outputs:glint:surface does not resolve to the glint shader (inputs:model = dbrdf-srbf)")
    # No Sdr identity (docs/conventions.md; exporters/src/usd.rs says why): no info:id, no source asset.
    if glint.GetShaderId() or glint.GetSourceTypes():
        fail("the glint shader names an Sdr node (info:id or a source type), which usd-core cannot resolve")
    missing = [n for n in ("lambda", "sigma", "centres", "coefficients_r", "coefficients_g", "coefficients_b", "rho_d", "f0", "table", "parameterisation", "brdf_convention", "frame_convention", "conventions") if not glint.GetInput(n)]
    if missing:
        fail(f"the glint shader lacks inputs {missing}")
    iso = bool(glint.GetInput("isotropic").Get())
    convention = glint.GetInput("brdf_convention").Get()
    if ("ring lobes" in convention) != iso or ("I0e" in convention) != iso:
        fail("brdf_convention does not state the formula of this layout (ring lobes with I0e for isotropic, point lobes otherwise)")
    for shader in (preview, glint):
        api = UsdShade.ConnectableAPI(shader.GetPrim())
        if not api or api.IsContainer() or not shader.GetPrim().IsA(UsdShade.Shader):
            fail(f"{shader.GetPath()} is not a connectable shader")
    workflow = preview.GetInput("useSpecularWorkflow").Get()
    if workflow not in (0, 1):
        fail(f"useSpecularWorkflow is {workflow}, not 0 or 1")
    if workflow == 1 and not preview.GetInput("specularColor"):
        fail("the specular workflow is on but specularColor is not authored")

    # A gprim bound to it.
    bound = []
    for prim in stage.Traverse():
        if prim.IsA(UsdGeom.Gprim):
            if not prim.HasAPI(UsdShade.MaterialBindingAPI):
                fail(f"{prim.GetPath()} lacks MaterialBindingAPI")
            m, _ = UsdShade.MaterialBindingAPI(prim).ComputeBoundMaterial()
            if not m or m.GetPath() != material.GetPath():
                fail(f"{prim.GetPath()} is not bound to {material.GetPath()}")
            bound.append(prim)
            if prim.IsA(UsdGeom.Mesh):
                mesh = UsdGeom.Mesh(prim)
                n = len(mesh.GetPointsAttr().Get() or [])
                counts = mesh.GetFaceVertexCountsAttr().Get() or []
                idx = mesh.GetFaceVertexIndicesAttr().Get() or []
                normals = UsdGeom.PrimvarsAPI(prim).GetPrimvar("normals")
                if n == 0 or sum(counts) != len(idx) or any(i < 0 or i >= n for i in idx):
                    fail(f"{prim.GetPath()}: inconsistent topology")
                if not normals or len(normals.Get()) != n or normals.GetInterpolation() != UsdGeom.Tokens.vertex:
                    fail(f"{prim.GetPath()}: primvars:normals missing or not per vertex")
    if not bound:
        fail("no gprim is bound to the material")

    # The camera, when the JSON names one: the view glint renders (docs/conventions.md section 4).
    cameras = [UsdGeom.Camera(p) for p in stage.Traverse() if p.IsA(UsdGeom.Camera)]
    want_cam = mat_json.get("camera")
    if want_cam is not None:
        if len(cameras) != 1:
            fail(f"expected one Camera prim, found {len(cameras)}")
        cam = cameras[0].GetCamera(Usd.TimeCode.Default())
        yfov = math.degrees(2 * math.atan(0.5 * cam.verticalAperture / cam.focalLength))
        compare("camera yfov", [yfov], [want_cam["yfov_deg"]])
        compare("camera aspect", [cam.horizontalAperture / cam.verticalAperture], [want_cam["width"] / want_cam["height"]])
        m = cam.transform
        compare("camera eye", list(m.ExtractTranslation()), want_cam["eye"])
        compare("camera forward", [-m[2][k] for k in range(3)], want_cam["forward"])
        compare("camera up", [m[1][k] for k in range(3)], want_cam["up"])
    # Tangents, when the mesh has them: per vertex, unit, signs +-1.
    for prim in bound:
        pv = UsdGeom.PrimvarsAPI(prim)
        t, signs = pv.GetPrimvar("tangents"), pv.GetPrimvar("tangentSigns")
        if t and t.HasValue():
            n = len(UsdGeom.Mesh(prim).GetPointsAttr().Get())
            tv, sv = t.Get(), (signs.Get() if signs else None)
            if len(tv) != n or sv is None or len(sv) != n or any(abs(abs(x) - 1) > 1e-6 for x in sv):
                fail(f"{prim.GetPath()}: primvars:tangents / tangentSigns are not one unit tangent and one sign per vertex")

    # The table asset resolves beside the stage.
    table = glint.GetInput("table").Get()
    if not table or not table.resolvedPath or not os.path.isfile(table.resolvedPath):
        fail(f"the table asset {table} does not resolve to a file")
    if glint.GetInput("parameterisation").Get() != "hemi-octahedral":
        fail("parameterisation is not hemi-octahedral")

    # The Material's `mtlx` surface: a MaterialX node (info:id ND_...). PyPI's usd-core is built
    # without MaterialX, so its Sdr registry does not know the node and its checkers report "invalid
    # shader node" for exactly this shader; in its place the shader is checked against MaterialX's
    # own node definition (the `materialx` package): the id exists, and every input is one of the
    # definition's, with a matching type.
    mtlx_shaders = mtlx_surface_shaders(material)
    checked = []
    for shader in mtlx_shaders:
        check_mtlx_shader(shader)
        checked.append(f"MaterialX {shader.GetIdAttr().Get()}")

    def known_mtlx_problem(problem):
        from pxr import Sdr

        text = str(problem)
        return any(f"<{s.GetPath()}> has invalid shader node" in text
                   or (f"'{s.GetIdAttr().Get()}'" in text and f"<{s.GetPath()}>" in text and "not found in sdrRegistry" in text)
                   for s in mtlx_shaders) and \
            not Sdr.Registry().GetShaderNodeByIdentifier(mtlx_shaders[0].GetIdAttr().Get())

    # UsdUtils.ComplianceChecker (removed from usd-core 26; UsdValidation replaces it).
    if hasattr(UsdUtils, "ComplianceChecker"):
        warnings.filterwarnings("ignore", category=DeprecationWarning)  # deprecated in 26, still the asked-for check
        checker = UsdUtils.ComplianceChecker(arkit=False, skipARKitRootLayerCheck=False, rootPackageOnly=False, skipVariants=False, verbose=False)
        checker.CheckCompliance(stage_path)
        problems = [p for p in list(checker.GetErrors()) + list(checker.GetFailedChecks()) if not known_mtlx_problem(p)]
        if problems:
            fail(f"ComplianceChecker: {problems[0]} ({len(problems)} problem(s))")
        checked.append("ComplianceChecker")
    try:
        from pxr import UsdValidation
    except ImportError:
        UsdValidation = None
    if UsdValidation is not None:
        registry = UsdValidation.ValidationRegistry()
        validators = registry.GetOrLoadAllValidators()
        context = UsdValidation.ValidationContext(validators)
        errors = [e for e in context.Validate(stage) if e.GetType() == UsdValidation.ValidationErrorType.Error
                  and not known_mtlx_problem(e.GetMessage())]
        if errors:
            e = errors[0]
            fail(f"UsdValidation {e.GetIdentifier()}: {e.GetMessage()} ({len(errors)} error(s))")
        checked.append(f"UsdValidation ({len(validators)} validators)")
    if not checked:
        fail("this usd-core has neither UsdUtils.ComplianceChecker nor UsdValidation")

    # Every number of the lobe table.
    def value(name):
        inp = glint.GetInput(name)
        if not inp:
            fail(f"the glint shader has no input '{name}'")
        return inp.Get()

    for key in ("lambda", "sigma", "f0"):
        compare(key, [value(key)], [mat_json[key]])
    compare("rho_d", list(value("rho_d")), mat_json["rho_d"])
    compare("centres", flat(value("centres")), flat(mat_json["centres"]))
    coefficients = mat_json["coefficients"]
    if len(coefficients) != 3:
        fail("the material JSON's coefficients are not 3 x J")
    for k, ch in enumerate("rgb"):
        compare(f"coefficients[{k}]", list(value(f"coefficients_{ch}")), coefficients[k])
    compared = "lobe table"
    if "fallback" in mat_json:
        fb = mat_json["fallback"]
        compared = "lobe table and fallback" + (" (with its anisotropy)" if fb.get("anisotropy") is not None else "")
        for key, name in [("diffuse_color", "diffuseColor"), ("metallic", "metallic"), ("roughness", "roughness"),
                          ("clearcoat", "clearcoat"), ("clearcoat_roughness", "clearcoatRoughness"),
                          ("specular_color", "specularColor"), ("use_specular_workflow", "useSpecularWorkflow")]:
            if key not in fb:
                continue
            if key == "specular_color" and not fb.get("use_specular_workflow"):
                continue
            inp = preview.GetInput(name)
            if not inp:
                fail(f"the UsdPreviewSurface has no input {name}")
            got = inp.Get()
            got = [float(x) for x in got] if hasattr(got, "__len__") else [float(got)]
            want = fb[key] if isinstance(fb[key], list) else [float(fb[key])]
            compare(f"fallback.{key}", got, want)
        if "anisotropy" in fb:
            # UsdPreviewSurface has no anisotropy: the exporter keeps it in the Material's customData.
            recorded = (material.GetPrim().GetCustomDataByKey("glint") or {}).get("fallback_anisotropy")
            if fb["anisotropy"] is None:
                if recorded is not None:
                    fail("customData glint.fallback_anisotropy is present but the fallback is isotropic")
            elif recorded is None:
                fail("the fallback is anisotropic but customData glint.fallback_anisotropy is missing")
            else:
                compare("fallback.anisotropy", [recorded.get("strength"), recorded.get("rotation")], fb["anisotropy"])

    j = len(mat_json["centres"])
    print(f"check_usd: OK {stage_path}: {len(bound)} bound gprim(s), J = {j}, {' + '.join(checked)} clean, {compared} match within {REL}")


if __name__ == "__main__":
    try:
        main()
    except SystemExit:
        raise
    except Exception as e:  # an unexpected failure is still one line
        fail(f"{type(e).__name__}: {e}")
