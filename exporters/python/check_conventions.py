#!/usr/bin/env python3
"""The BRDF implemented from docs/conventions.md alone, checked against an exported p(h) table.

usage: check_conventions.py TABLE_ph.EXR LOBES.json

Written from the page, not from glint's code: §1 (point lobes for anisotropic layouts, ring lobes
exp(2 lambda (cos_h cos_j - 1)) I0(2 lambda sin_h sin_j) for isotropic ones) and §3 (the
hemi-octahedral, corner-aligned table). It decodes every texel of the EXR to its half-vector,
evaluates p(h) from the lobe JSON (`<name>_lobes.json`, the glTF extras' object: lambda, isotropic,
centres, coefficients) and compares: the largest difference must be <= 1e-3 of the peak. It also checks
the header's plain attributes against the JSON, and that reading an isotropic layout's centres as
point lobes (what the old convention string said) would NOT match — so a pass means the page's
formula is the one the table holds.

Prints "check_conventions: OK ..." and exits 0, or one line "check_conventions: FAIL: ..." and exits 1.
"""

import json
import sys

import numpy as np


def fail(msg):
    print("check_conventions: FAIL: " + " ".join(str(msg).split()))
    sys.exit(1)


def decode(r):
    """§3: texel (x, y) -> unit half-vector, arrays of shape (r, r, 3); row y = 0 first."""
    u = np.arange(r) / (r - 1)
    uu, vv = np.meshgrid(u, u)  # uu varies along x (columns), vv along y (rows)
    a, b = 2 * uu - 1, 2 * vv - 1
    px, py = (a + b) / 2, (a - b) / 2
    pz = np.maximum(1 - np.abs(px) - np.abs(py), 0)
    h = np.stack([px, py, pz], axis=-1)
    return h / np.linalg.norm(h, axis=-1, keepdims=True)


def p_of_h(h, lobes, point_lobes=None):
    """§1: p(h) per channel. `point_lobes` forces the anisotropic form (for the negative check)."""
    lam = float(lobes["lambda"])
    xi = np.asarray(lobes["centres"], dtype=np.float64)
    c = np.asarray(lobes["coefficients"], dtype=np.float64)  # 3 x J
    iso = bool(lobes["isotropic"]) if point_lobes is None else not point_lobes
    if iso:
        cos_h = np.clip(h[..., 2], -1, 1)[..., None]
        sin_h = np.sqrt(np.maximum(1 - cos_h**2, 0))
        cos_j, sin_j = xi[:, 2], np.sqrt(np.maximum(1 - xi[:, 2] ** 2, 0))
        # exp(2 lambda (cos_h cos_j - 1)) I0(2 lambda sin_h sin_j); np.i0 is I0 (fine below x ~ 700).
        g = np.exp(2 * lam * (cos_h * cos_j - 1)) * np.i0(2 * lam * sin_h * sin_j)
    else:
        g = np.exp(2 * lam * (h @ xi.T - 1))
    return g @ c.T  # (..., 3)


def main():
    if len(sys.argv) != 3:
        fail("usage: check_conventions.py TABLE_ph.EXR LOBES.json")
    try:
        import OpenEXR
    except ImportError as e:
        fail(f"OpenEXR is not importable ({e})")
    with open(sys.argv[2], encoding="utf-8") as f:
        lobes = json.load(f)
    exr = OpenEXR.File(sys.argv[1])
    header = exr.header()
    channels = exr.channels()
    if "RGB" in channels:
        table = np.asarray(channels["RGB"].pixels, dtype=np.float64)
    else:
        table = np.stack([np.asarray(channels[k].pixels, dtype=np.float64) for k in "RGB"], axis=-1)
    r = table.shape[0]
    if table.shape != (r, r, 3):
        fail(f"the table is {table.shape}, not R x R x 3")
    for k, ch in enumerate("rgb"):
        got = float(header.get(f"glint.rho_d_{ch}", np.nan))
        if abs(got - lobes["rho_d"][k]) > 1e-6 * max(1.0, abs(lobes["rho_d"][k])):
            fail(f"glint.rho_d_{ch} = {got} but the lobe JSON says {lobes['rho_d'][k]}")
    if int(header.get("glint.isotropic", -1)) != int(bool(lobes["isotropic"])):
        fail("glint.isotropic does not match the lobe JSON")
    convention = header.get("glint.brdf_convention", "")
    if isinstance(convention, bytes):
        convention = convention.decode()
    if ("ring lobes" in convention) != bool(lobes["isotropic"]):
        fail("glint.brdf_convention does not name the lobe form of this layout")
    want = p_of_h(decode(r), lobes)
    peak = float(want.max())
    if not peak > 0:
        fail("the material has no specular lobe to check")
    err = float(np.abs(table - want).max()) / peak
    if err > 1e-3:
        fail(f"the table differs from docs/conventions.md's p(h) by {err:.2e} of the peak (> 1e-3)")
    note = ""
    if lobes["isotropic"]:
        wrong = p_of_h(decode(r), lobes, point_lobes=True)
        wrong_err = float(np.abs(table - wrong).max()) / peak
        if wrong_err < 0.1:
            fail(f"point lobes at the ring centres match the table too ({wrong_err:.2e}): the check cannot tell the forms apart")
        note = f"; as point lobes it would be {wrong_err:.0%} off"
    form = "ring lobes" if lobes["isotropic"] else "point lobes"
    print(f"check_conventions: OK {sys.argv[1]}: {r}x{r} table = docs/conventions.md p(h) ({form}, J = {len(lobes['centres'])}) within {err:.1e} of the peak{note}")


if __name__ == "__main__":
    main()
