"""``python -m glint_mitsuba bench SCENE.xml``: render time and noise at equal spp of the glint BSDF
against Mitsuba's own ``roughconductor`` of a similar width, on a scene ``glint export --formats
mitsuba`` wrote. Prints a Markdown table (with a "measured on" line) for docs/benchmarks.md.

Materials, all rendered by the scene's ``glint_direct`` integrator (same camera, map, shadow rays):
- the scene's own glint material (the table EXR);
- ``glint λ=81``: one glint lobe at the normal (isotropic-1, λ = 81.06, σ = π/40, the paper's width),
  no diffuse term;
- ``roughconductor GGX α`` and ``Beckmann α``: Mitsuba's microfacet conductor of about that width
  (α = 0.11), no diffuse term.

Noise: relative RMSE over object pixels of an N-spp image against a 16×-spp image of the same
material (its own converged picture), averaged over seeds. Time: wall seconds of the render, after a
first render that compiles the kernels.
"""

from __future__ import annotations

import json
import math
import os
import platform
import re
import time

import numpy as np

LAMBDA_PAPER = 81.06


def _cpu() -> str:
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


def _one_lobe_json(path: str) -> None:
    sigma = math.pi / 40
    with open(path, "w", encoding="utf-8") as f:
        json.dump({
            "model": "dbrdf-srbf", "version": 1, "lambda": LAMBDA_PAPER, "sigma": sigma,
            "layout": "isotropic-1", "isotropic": True, "centres": [[0.0, 0.0, 1.0]],
            "coefficients": [[20.0], [20.0], [20.0]], "rho_d": [0.0, 0.0, 0.0], "f0": 1.0,
        }, f)


def run(scene_path: str, spps=(16, 64), seeds: int = 3, alpha: float = 0.11) -> str:
    import mitsuba as mi

    import glint_mitsuba
    from glint_mitsuba.cli import _quiet_logger

    variant = glint_mitsuba.default_variant()
    mi.set_variant(variant)
    _quiet_logger(mi)
    glint_mitsuba.register()
    folder = os.path.dirname(os.path.abspath(scene_path))
    mi.Thread.thread().file_resolver().prepend(folder)
    with open(scene_path, encoding="utf-8") as f:
        xml = f.read()
    block = re.search(r"<bsdf type=\"glint\">.*?</bsdf>", xml, flags=re.S)
    if not block:
        raise ValueError(f"{scene_path}: no <bsdf type=\"glint\"> block (not a glint export)")
    one_lobe = os.path.join(folder, "bench_one_lobe.json")
    _one_lobe_json(one_lobe)
    materials = [
        ("glint, the scene's material (table)", block.group(0)),
        (f"glint, one lobe λ = {LAMBDA_PAPER}", f'<bsdf type="glint"><string name="filename" value="{one_lobe}"/></bsdf>'),
        (f"roughconductor GGX α = {alpha}", f'<bsdf type="roughconductor"><string name="material" value="none"/><string name="distribution" value="ggx"/><float name="alpha" value="{alpha}"/></bsdf>'),
        (f"roughconductor Beckmann α = {alpha}", f'<bsdf type="roughconductor"><string name="material" value="none"/><string name="distribution" value="beckmann"/><float name="alpha" value="{alpha}"/></bsdf>'),
    ]
    rows = []
    for label, bsdf in materials:
        text = xml.replace(block.group(0), bsdf)

        def render(spp, seed):
            scene = mi.load_string(text, spp=spp)
            t0 = time.perf_counter()
            img = np.array(mi.render(scene, seed=seed), dtype=np.float64)
            return img, time.perf_counter() - t0

        ref, _ = render(16 * max(spps), 1000)
        mask = ref[:, :, 3] > 0.5
        den = np.sqrt(np.sum(ref[mask][:, :3] ** 2))
        cells = []
        for spp in spps:
            render(spp, 999)  # compile the kernels for this size
            errs, secs = [], []
            for seed in range(seeds):
                img, dt = render(spp, seed)
                errs.append(np.sqrt(np.sum((img[mask][:, :3] - ref[mask][:, :3]) ** 2)) / den)
                secs.append(dt)
            cells.append((spp, float(np.mean(errs)), float(np.median(secs))))
        rows.append((label, cells))
    film = re.search(r'name="width" value="(\d+)".*?name="height" value="(\d+)"', xml, flags=re.S)
    size = f"{film.group(1)}×{film.group(2)}" if film else "?"
    out = [f"Measured on: {_cpu()}, {os.cpu_count()} threads, mitsuba {mi.__version__} `{variant}`, "
           f"scene `{os.path.basename(scene_path)}` at {size}, integrator `glint_direct`; noise = relative RMSE over object "
           f"pixels against the same material at {16 * max(spps)} spp, mean of {seeds} seeds; time = median render seconds.", ""]
    out.append("| material | " + " | ".join(f"{s} spp: noise, time" for s in spps) + " |")
    out.append("|---|" + "---|" * len(spps))
    for label, cells in rows:
        out.append(f"| {label} | " + " | ".join(f"{100 * e:.2f} %, {t:.2f} s" for _, e, t in cells) + " |")
    os.remove(one_lobe)
    return "\n".join(out)
