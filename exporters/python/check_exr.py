#!/usr/bin/env python3
"""Checks a glint p(h) table EXR with the OpenEXR Python package (an independent reader).

usage: check_exr.py TABLE.exr EXPECTED.npy

EXPECTED.npy is float32 of shape (R, R, 3): row y, column x, channel R/G/B (row 0 = first scan line).
Checks that the file is a single-part scan-line RGB FLOAT image of R x R pixels whose pixels equal the
array bit for bit, and that the glint header attributes exist (parameterisation "hemi-octahedral...").

Prints "check_exr: OK ..." and exits 0, or prints one line "check_exr: FAIL: <reason>" and exits 1.
"""

import sys

REQUIRED = (
    "glint.model", "glint.version", "glint.lambda", "glint.sigma", "glint.f0", "glint.rho_d",
    "glint.parameterisation", "glint.frame_convention", "glint.brdf_convention",
)


def fail(msg):
    print("check_exr: FAIL: " + " ".join(str(msg).split()))
    sys.exit(1)


def main():
    if len(sys.argv) != 3:
        fail("usage: check_exr.py TABLE.exr EXPECTED.npy")
    exr_path, npy_path = sys.argv[1], sys.argv[2]
    try:
        import numpy as np
        import OpenEXR
    except ImportError as e:
        fail(f"{e}; pip install OpenEXR numpy")
    expected = np.load(npy_path)
    if expected.dtype != np.float32 or expected.ndim != 3 or expected.shape[2] != 3 or expected.shape[0] != expected.shape[1]:
        fail(f"{npy_path}: expected float32 (R, R, 3), got {expected.dtype} {expected.shape}")
    try:
        f = OpenEXR.File(exr_path)
    except Exception as e:
        fail(f"OpenEXR cannot read {exr_path}: {e}")
    header = f.header()
    missing = [k for k in REQUIRED if k not in header]
    if missing:
        fail(f"missing header attributes {missing}")
    if not str(header["glint.parameterisation"]).startswith("hemi-octahedral"):
        fail(f"glint.parameterisation is {header['glint.parameterisation']!r}")
    for k in ("glint.lambda", "glint.sigma", "glint.f0"):
        v = np.asarray(header[k])
        if v.size != 1 or v.dtype.kind != "f":
            fail(f"{k} is not a float attribute: {header[k]!r}")
    if np.asarray(header["glint.rho_d"]).size != 3:
        fail("glint.rho_d does not hold 3 numbers")
    channels = f.channels()
    if "RGB" in channels:
        pixels = channels["RGB"].pixels
    elif all(c in channels for c in "RGB"):
        pixels = np.stack([channels[c].pixels for c in "RGB"], axis=-1)
    else:
        fail(f"no R, G, B channels (found {sorted(channels)})")
    if pixels.dtype != np.float32:
        fail(f"pixels are {pixels.dtype}, not 32-bit float")
    if pixels.shape != expected.shape:
        fail(f"image is {pixels.shape}, expected {expected.shape}")
    if not np.array_equal(pixels.view(np.uint32), expected.view(np.uint32)):
        diff = np.argwhere(pixels.view(np.uint32) != expected.view(np.uint32))[0]
        y, x, c = (int(v) for v in diff)
        fail(f"pixel (x={x}, y={y}) channel {'RGB'[c]}: file {pixels[y, x, c]!r} vs expected {expected[y, x, c]!r}")
    print(f"check_exr: OK {exr_path}: {expected.shape[0]}x{expected.shape[1]} RGB float32 equal bit for bit, {len(REQUIRED)} glint attributes present")


if __name__ == "__main__":
    try:
        main()
    except SystemExit:
        raise
    except Exception as e:  # an unexpected failure is still one line
        fail(f"{type(e).__name__}: {e}")
