"""``python -m glint_mitsuba render SCENE.xml --out OUT.exr [--spp N] [--variant V] [--seed S]
[--lambertian]``: renders a scene written by ``glint export --formats mitsuba`` and writes a linear
RGBA float EXR (A = coverage); prints one JSON line. ``python -m glint_mitsuba bench SCENE.xml``: time
and noise at equal spp against ``roughconductor`` (see ``bench.py``). Errors: one line on stderr, exit
status 1."""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np


class _Parser(argparse.ArgumentParser):
    def error(self, message):
        raise _UsageError(message)


class _UsageError(Exception):
    pass


def _parser():
    p = _Parser(prog="python -m glint_mitsuba", description=__doc__)
    sub = p.add_subparsers(dest="command")
    r = sub.add_parser("render", help="render a glint Mitsuba scene to an RGBA EXR")
    r.add_argument("scene")
    r.add_argument("-o", "--out", required=True)
    r.add_argument("--spp", type=int, default=None)
    r.add_argument("--variant", choices=["llvm_ad_rgb", "scalar_rgb"], default=None)
    r.add_argument("--seed", type=int, default=0)
    r.add_argument("--lambertian", action="store_true",
                   help="replace every glint BSDF by its Lambertian copy (rho_d only)")
    b = sub.add_parser("bench", help="time and noise at equal spp: glint BSDF vs roughconductor (Markdown)")
    b.add_argument("scene")
    b.add_argument("--spp", default="16,64", help="comma-separated sample counts")
    b.add_argument("--seeds", type=int, default=3)
    b.add_argument("--alpha", type=float, default=0.11)
    return p


def write_rgba_exr(path: str, image: np.ndarray) -> None:
    """Writes an H x W x 4 (or x 3) float image as a 32-bit float EXR (channels R, G, B[, A])."""
    import OpenEXR

    image = np.asarray(image, dtype=np.float32)
    names = "RGBA"[: image.shape[2]]
    channels = {c: np.ascontiguousarray(image[:, :, k]) for k, c in enumerate(names)}
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    tmp = path + ".tmp.exr"
    OpenEXR.File(header, channels).write(tmp)
    os.replace(tmp, path)


def _quiet_logger(mi):
    """stdout carries only the JSON line: Mitsuba's log goes to stderr, errors only (they are raised
    as exceptions and reported in one line anyway)."""
    class _Stderr(mi.Appender):
        def append(self, level, text):
            print(text, file=sys.stderr)

        def log_progress(self, progress, name, formatted, eta, ptr=None):
            pass

    logger = mi.logger() if hasattr(mi, "logger") else mi.Thread.thread().logger()
    logger.clear_appenders()
    logger.add_appender(_Stderr())
    logger.set_log_level(mi.LogLevel.Error)


def render(scene_path: str, out: str, spp=None, variant=None, seed: int = 0, lambertian: bool = False) -> dict:
    import mitsuba as mi

    import glint_mitsuba

    if spp is not None and spp < 1:
        raise ValueError("--spp must be >= 1")
    if not os.path.isfile(scene_path):
        raise FileNotFoundError(f"{scene_path}: no such scene file")
    if variant is None:
        variant = glint_mitsuba.default_variant()
    mi.set_variant(variant)
    _quiet_logger(mi)
    glint_mitsuba.register(lambertian=lambertian)
    kwargs = {} if spp is None else {"spp": int(spp)}
    scene = mi.load_file(scene_path, **kwargs)
    sensor = scene.sensors()[0]
    used_spp = sensor.sampler().sample_count()
    t0 = time.perf_counter()
    img = mi.render(scene, seed=int(seed))
    img = np.array(img, dtype=np.float32)
    seconds = time.perf_counter() - t0
    if img.ndim == 2:
        img = img[:, :, None]
    if img.shape[2] == 3:  # film without alpha: coverage unknown, write 3 channels
        pass
    os.makedirs(os.path.dirname(os.path.abspath(out)), exist_ok=True)
    write_rgba_exr(out, img[:, :, :4])
    return {"out": out, "seconds": round(seconds, 3), "variant": variant, "spp": int(used_spp)}


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    try:
        args = _parser().parse_args(argv)
        if args.command == "bench":
            from glint_mitsuba import bench

            spps = tuple(int(s) for s in args.spp.split(","))
            if not spps or min(spps) < 1 or args.seeds < 1:
                raise _UsageError("--spp takes positive counts and --seeds at least 1")
            print(bench.run(args.scene, spps, args.seeds, args.alpha))
            return 0
        if args.command != "render":
            raise _UsageError("expected the command 'render' or 'bench' (python -m glint_mitsuba render SCENE.xml --out OUT.exr)")
        info = render(args.scene, args.out, args.spp, args.variant, args.seed, args.lambertian)
    except SystemExit:
        raise
    except BaseException as e:  # one line on stderr, exit 1
        msg = " ".join(str(e).split()) or type(e).__name__
        print(f"glint_mitsuba: error: {msg}", file=sys.stderr)
        return 1
    print(json.dumps(info))
    return 0
