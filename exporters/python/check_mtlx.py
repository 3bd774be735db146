"""Checks a glint MaterialX document with MaterialX's own library (PyPI `materialx` 1.39).

Usage: check_mtlx.py DOC.mtlx EXPECTED.json

Loads the document, imports MaterialX's standard data libraries, runs `validate()`, and compares the
OpenPBR Surface's inputs with EXPECTED.json (an object {input name: number or [r, g, b]}) within
f32 precision. Every expected input must be set; the shader must be an `open_pbr_surface` bound by
a `surfacematerial`. Prints "check_mtlx: OK ..." and exits 0, or prints the first problem and exits 1.
"""

import json
import sys

import MaterialX as mx


def fail(msg):
    print(f"check_mtlx: FAIL {msg}")
    sys.exit(1)


def main():
    path, expected_path = sys.argv[1], sys.argv[2]
    with open(expected_path) as f:
        expected = json.load(f)
    doc = mx.createDocument()
    try:
        mx.readFromXmlFile(doc, path)
    except Exception as e:  # MaterialX raises its own exception types
        fail(f"cannot read {path}: {e}")
    lib = mx.createDocument()
    mx.loadLibraries(mx.getDefaultDataLibraryFolders(), mx.getDefaultDataSearchPath(), lib)
    doc.importLibrary(lib)
    ok, message = doc.validate()
    if not ok:
        fail(f"validate(): {message.strip()}")
    materials = [n for n in doc.getMaterialNodes()]
    if len(materials) != 1:
        fail(f"{len(materials)} material nodes, expected 1")
    shaders = mx.getShaderNodes(materials[0])
    if len(shaders) != 1 or shaders[0].getCategory() != "open_pbr_surface":
        fail(f"the material's surface shader is {[s.getCategory() for s in shaders]}, expected open_pbr_surface")
    shader = shaders[0]
    nodedef = shader.getNodeDef()
    if nodedef is None or nodedef.getName() != "ND_open_pbr_surface_surfaceshader":
        fail(f"the shader's node definition is {nodedef.getName() if nodedef else None}")
    for name, want in expected.items():
        inp = shader.getInput(name)
        if inp is None:
            fail(f"input {name} is not set")
        got = inp.getValue()
        got = [float(x) for x in got.asTuple()] if hasattr(got, "asTuple") else [float(got)]
        want = want if isinstance(want, list) else [want]
        if len(got) != len(want) or any(abs(g - w) > 1e-6 * max(1.0, abs(w)) for g, w in zip(got, want)):
            fail(f"input {name}: document {got} vs expected {want}")
    print(f"check_mtlx: OK {path}: validate() clean, open_pbr_surface with {len(expected)} inputs as expected")


if __name__ == "__main__":
    main()
