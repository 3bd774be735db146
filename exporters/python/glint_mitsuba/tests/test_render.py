"""The ``glint_direct`` integrator and the command line: white furnace, glossy furnace (albedo per
pixel; no self-shadowing on a convex tessellated sphere thanks to the smooth-surface shadow origins
of docs/conventions.md §6), pixel-centre rays and background (§4), coverage alpha, the CLI."""

import json
import math
import os
import subprocess
import sys
import time

import numpy as np
import pytest

from glint_mitsuba import testing as T
from glint_mitsuba.material import Material

mi = pytest.importorskip("mitsuba")
dr = pytest.importorskip("drjit")

SRC = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "src")


def render(xml, spp, seed=0):
    scene = mi.load_file(xml)
    t0 = time.perf_counter()
    img = np.array(mi.render(scene, seed=seed, spp=spp), dtype=float)
    return scene, img, time.perf_counter() - t0


def lambertian(rho):
    return Material(lam=10.0, isotropic=True, f0=0.04, rho_d=np.full(3, rho), centres=np.zeros((0, 3)),
                    coefficients=np.zeros((3, 0)), source="lambertian")


def test_white_furnace(variant, tmp_path, capsys):
    """A Lambertian sphere (rho_d = 0.5) under a constant environment of radiance 1: every object
    pixel is 0.5 in expectation, every background pixel exactly 1, alpha exactly 0 or 1."""
    xml = T.write_sphere_scene(str(tmp_path), material=lambertian(0.5), width=32, height=24)
    spp = 64 if variant.startswith("llvm") else 4
    _, img, secs = render(xml, spp)
    with capsys.disabled():
        print(f"\n[{variant}] furnace 32x24 at {spp} spp: {secs:.3f} s")
    alpha = img[..., 3]
    assert set(np.unique(alpha)) == {0.0, 1.0}
    obj = img[alpha == 1][:, :3]
    assert len(obj) > 100
    np.testing.assert_allclose(img[alpha == 0][:, :3], 1.0, rtol=0, atol=1e-6)
    mean = obj.mean()
    sigma = obj.std() / math.sqrt(obj.size)
    assert abs(mean - 0.5) < max(4 * sigma, 2e-3), (mean, sigma)
    assert abs(mean - 0.5) < 0.01
    # the same without the per-pixel stratification (every random number from the sampler)
    scene = mi.load_file(xml)
    plain = mi.load_dict({"type": "glint_direct", "stratified": False, "ray_offset": 3.5e-4})
    img2 = np.array(mi.render(scene, integrator=plain, spp=spp, seed=1), dtype=float)
    np.testing.assert_array_equal(img2[..., 3], alpha)
    obj2 = img2[alpha == 1][:, :3]
    assert abs(obj2.mean() - 0.5) < max(4 * obj2.std() / math.sqrt(obj2.size), 2e-3)


def test_glossy_furnace_equals_albedo(fast_variant, tmp_path):
    """A glossy isotropic material under a constant environment: each pixel is the BRDF's albedo
    for its eye direction (quadrature of bsdf.eval at the pixel's hit)."""
    jit = fast_variant.startswith("llvm")
    m = T.example_material(isotropic=True)
    xml = T.write_sphere_scene(str(tmp_path), material=m, width=32, height=24, use_json=True)
    scene, img, _ = render(xml, 1024 if jit else 16)
    sensor = scene.sensors()[0]
    rng = np.random.default_rng(0)
    ys, xs = np.nonzero(img[..., 3] == 1)
    pick = rng.choice(len(xs), 24 if jit else 4, replace=False)
    dirs, w = T.hemisphere_quadrature(128 if jit else 48)
    ctx = mi.BSDFContext()
    rel = []
    for i in pick:
        x, y = int(xs[i]), int(ys[i])
        ray, _ = sensor.sample_ray(0.0, 0.5, mi.Point2f((x + 0.5) / 32, (y + 0.5) / 24), mi.Point2f(0.5))
        if jit:
            si = scene.ray_intersect(ray)
            si = dr.gather(type(si), si, dr.zeros(mi.UInt32, len(dirs)))
            wl = mi.Vector3f(*[mi.Float(dirs[:, k].astype(np.float32)) for k in range(3)])
            f = np.array(si.bsdf().eval(ctx, si, wl)).reshape(3, -1).T
        else:
            si = scene.ray_intersect(ray)
            f = np.array([list(si.bsdf().eval(ctx, si, mi.Vector3f(*map(float, d)))) for d in dirs])
        albedo = (f * w[:, None]).sum(0)
        rel.append(img[y, x, :3] / albedo - 1)
    rel = np.array(rel)
    # per pixel: ~1 % noise at 1024 spp (llvm), ~8 % at 16 spp (scalar)
    assert np.max(np.abs(rel)) < (0.05 if jit else 0.3), rel
    assert np.all(np.abs(rel.mean(0)) < (0.008 if jit else 0.15)), rel.mean(0)


def test_pixel_centre_rays_background_and_coverage(variant, tmp_path):
    """Every sample of a pixel is the ray through its centre (§4): background pixels equal the
    environment in that direction, computed here from the camera's lookat alone; alpha is 1 exactly
    where that ray hits the mesh."""
    h_env, w_env = 64, 128
    th = ((np.arange(h_env) / (h_env - 1)) * np.pi)[:, None]
    ph = ((np.arange(w_env) + 0.5) / w_env * 2 * np.pi)[None, :]
    env = np.stack([0.5 + 0.5 * np.cos(th) + 0 * ph, 0.5 + 0.4 * np.sin(3 * ph) * np.sin(th),
                    0.2 + 0.1 * np.cos(2 * th) * np.cos(ph)], -1)
    xml = T.write_sphere_scene(str(tmp_path), material=lambertian(0.5), env=env, width=40, height=30)
    scene, img, _ = render(xml, 8 if variant.startswith("llvm") else 2, seed=3)
    eye, target, up = np.array([0.0, 0.0, 4.0]), np.zeros(3), np.array([0.0, 1.0, 0.0])
    fwd = (target - eye) / np.linalg.norm(target - eye)
    right = np.cross(fwd, up)
    right /= np.linalg.norm(right)
    upv = np.cross(right, fwd)
    wd, ht = 40, 30
    t = math.tan(math.radians(40) / 2)
    yy, xx = np.mgrid[0:ht, 0:wd]
    ndc_x = 2 * (xx + 0.5) / wd - 1
    ndc_y = 1 - 2 * (yy + 0.5) / ht
    d = (ndc_x * t * wd / ht)[..., None] * right + (ndc_y * t)[..., None] * upv + fwd
    d /= np.linalg.norm(d, axis=-1)[..., None]
    d = d.reshape(-1, 3)
    env_emitter = scene.environment()
    hit = np.zeros(len(d), bool)
    rad = np.zeros((len(d), 3))
    for k in range(len(d)) if not dr.is_jit_v(mi.Float) else [None]:
        sl = slice(None) if k is None else slice(k, k + 1)
        dd = d[sl]
        if k is None:
            o = mi.Point3f(*[mi.Float(np.full(len(dd), eye[j], np.float32)) for j in range(3)])
            v = mi.Vector3f(*[mi.Float(dd[:, j].astype(np.float32)) for j in range(3)])
        else:
            o = mi.Point3f(*map(float, eye))
            v = mi.Vector3f(*map(float, dd[0]))
        si = scene.ray_intersect(mi.Ray3f(o, v))
        hit[sl] = np.array(si.is_valid()).reshape(-1)
        q = dr.zeros(mi.SurfaceInteraction3f)
        q.wi = -v
        rad[sl] = np.array(env_emitter.eval(q)).reshape(3, -1).T
    alpha = img[..., 3].reshape(-1)
    np.testing.assert_array_equal(alpha, hit.astype(float))
    bg = ~hit
    np.testing.assert_allclose(img[..., :3].reshape(-1, 3)[bg], rad[bg], rtol=2e-4, atol=1e-5)


def test_smooth_surface_shadow_origin(variant, tmp_path):
    """The integrator's smooth-surface point equals q = p - sum b_i min(0, (p - p_i).n_i) n_i."""
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    n = np.array([[-0.4, -0.3, 1], [0.5, -0.2, 1], [-0.1, 0.6, 1]], float)
    n /= np.linalg.norm(n, axis=1)[:, None]
    T.write_ply(str(tmp_path / "tri.ply"), v, n, [[0, 1, 2]])
    scene = mi.load_dict({"type": "scene", "t": {"type": "ply", "filename": str(tmp_path / "tri.ply")},
                          "integrator": {"type": "glint_direct"}})
    integ = scene.integrator()
    for b1, b2 in [(0.2, 0.3), (0.6, 0.1), (0.05, 0.9)]:
        p = (1 - b1 - b2) * v[0] + b1 * v[1] + b2 * v[2]
        ray = mi.Ray3f(mi.Point3f(*map(float, p + [0, 0, 1])), mi.Vector3f(0, 0, -1))
        si = scene.ray_intersect(ray)
        q = np.array(integ.smooth_point(scene, si, si.is_valid())).reshape(-1)
        b = [1 - b1 - b2, b1, b2]
        want = p - sum(b[k] * min(0.0, (p - v[k]) @ n[k]) * n[k] for k in range(3))
        np.testing.assert_allclose(q, want, atol=1e-6)
        assert want[2] > 1e-3  # the smooth surface lies above this facet


def run_cli(*args):
    env = dict(os.environ)
    env["PYTHONPATH"] = SRC + os.pathsep + env.get("PYTHONPATH", "")
    return subprocess.run([sys.executable, "-m", "glint_mitsuba", *args], capture_output=True, text=True,
                          env=env, timeout=300)


@pytest.mark.parametrize("cli_variant", ["scalar_rgb", "llvm_ad_rgb"])
def test_cli_render(tmp_path, cli_variant):
    pytest.importorskip("mitsuba")
    if cli_variant.startswith("llvm") and not os.environ.get("DRJIT_LIBLLVM_PATH"):
        pytest.skip("DRJIT_LIBLLVM_PATH is unset (CI sets it)")
    import OpenEXR

    xml = T.write_sphere_scene(str(tmp_path), width=24, height=18, spp=4)
    out = str(tmp_path / "out" / "img.exr")
    r = run_cli("render", xml, "--out", out, "--spp", "2", "--variant", cli_variant, "--seed", "7")
    assert r.returncode == 0, r.stderr
    info = json.loads(r.stdout.strip().splitlines()[-1])
    assert info["out"] == out and info["variant"] == cli_variant and info["spp"] == 2
    assert info["seconds"] >= 0
    f = OpenEXR.File(out, separate_channels=True)
    ch = f.channels()
    assert set(ch) == {"R", "G", "B", "A"}
    a = np.asarray(ch["A"].pixels)
    assert a.shape == (18, 24) and set(np.unique(a)) == {0.0, 1.0}
    assert np.asarray(ch["R"].pixels).dtype == np.float32

    lam = run_cli("render", xml, "--out", str(tmp_path / "lam.exr"), "--spp", "2", "--variant", cli_variant,
                  "--lambertian")
    assert lam.returncode == 0, lam.stderr
    g = OpenEXR.File(str(tmp_path / "lam.exr"), separate_channels=True).channels()
    # the Lambertian copy (rho_d only) is darker than the glossy material under a white furnace
    obj = a == 1
    assert np.asarray(g["G"].pixels)[obj].mean() < np.asarray(ch["G"].pixels)[obj].mean()
    np.testing.assert_allclose(np.asarray(g["G"].pixels)[obj].mean(), 0.22, rtol=0.05)


def test_cli_errors(tmp_path):
    r = run_cli("render", str(tmp_path / "missing.xml"), "--out", str(tmp_path / "x.exr"), "--variant",
                "scalar_rgb")
    assert r.returncode == 1
    assert len(r.stderr.strip().splitlines()) == 1 and "missing.xml" in r.stderr
    r = run_cli("render", "--out", "x.exr")
    assert r.returncode == 1 and len(r.stderr.strip().splitlines()) == 1
    bad = tmp_path / "bad.xml"
    bad.write_text(T.scene_xml("nothere", eye=(0, 0, 4), target=(0, 0, 0)))
    r = run_cli("render", str(bad), "--out", str(tmp_path / "x.exr"), "--variant", "scalar_rgb")
    assert r.returncode == 1 and len(r.stderr.strip().splitlines()) == 1
