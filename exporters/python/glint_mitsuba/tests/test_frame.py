"""The local frame of docs/conventions.md §2 on a real mesh: x = the PLY's interpolated tangent
(Gram–Schmidt against the shading normal), y = (n x x) sign(handedness). Turning the tangent
attribute by 90 degrees about n must equal turning the lobes by 90 degrees the other way."""

import math
import os

import numpy as np
import pytest

from glint_mitsuba import testing as T
from glint_mitsuba.material import Material

mi = pytest.importorskip("mitsuba")
dr = pytest.importorskip("drjit")


def rotated(m: Material, fn) -> Material:
    c = np.array([fn(x) for x in m.centres])
    return Material(lam=m.lam, isotropic=False, f0=m.f0, rho_d=m.rho_d, centres=c,
                    coefficients=m.coefficients, source="rotated")


def quad_scene(folder, name, js, tangent, handedness=1.0, tilt=0.0):
    v, n, f, uv, _, _ = T.quad(2.0, normal_tilt=tilt)
    T.write_ply(os.path.join(folder, f"{name}.ply"), v, n, f, uv, np.tile(tangent, (4, 1)),
                np.full(4, handedness))
    return mi.load_dict({"type": "scene", "q": {"type": "ply", "filename": os.path.join(folder, f"{name}.ply"),
                                                "bsdf": {"type": "glint", "filename": js}}})


def eval_on_mesh(scene, points, eye, lights):
    """bsdf.eval at the hits of rays from direction ``eye`` onto ``points`` for each light direction
    (world space); returns (len(points), len(lights), 3)."""
    ctx = mi.BSDFContext()
    out = np.zeros((len(points), len(lights), 3))
    jit = dr.is_jit_v(mi.Float)
    for i, p in enumerate(points):
        o = np.asarray(p) + 3 * np.asarray(eye)
        if jit:
            n = len(lights)
            ray = mi.Ray3f(mi.Point3f(*[mi.Float(np.full(n, o[k], np.float32)) for k in range(3)]),
                           mi.Vector3f(*[mi.Float(np.full(n, -eye[k], np.float32)) for k in range(3)]))
            si = scene.ray_intersect(ray)
            assert dr.all(si.is_valid())
            wl = mi.Vector3f(*[mi.Float(lights[:, k].astype(np.float32)) for k in range(3)])
            f = si.bsdf(ray).eval(ctx, si, si.to_local(wl))
            out[i] = np.array(f).reshape(3, -1).T
        else:
            ray = mi.Ray3f(mi.Point3f(*map(float, o)), mi.Vector3f(*map(float, -np.asarray(eye))))
            si = scene.ray_intersect(ray)
            assert si.is_valid()
            bsdf = si.bsdf(ray)
            for j, l in enumerate(lights):
                out[i, j] = list(bsdf.eval(ctx, si, si.to_local(mi.Vector3f(*map(float, l)))))
    return out


def reference(m, points, eye, lights, tilt, x_axis, handedness=1.0):
    """float64 f_r * cos in the frame §2 builds from the quad's (constant) normal and tangent."""
    n = np.array([tilt, 0.0, 1.0]) / math.hypot(tilt, 1.0)
    t = np.asarray(x_axis, float)
    x = t - n * (n @ t)
    x /= np.linalg.norm(x)
    y = np.cross(n, x) * (1.0 if handedness >= 0 else -1.0)
    frame = np.stack([x, y, n])
    e = frame @ np.asarray(eye)
    ls = lights @ frame.T
    f = m.f_r(ls, np.tile(e, (len(ls), 1))) * np.maximum(ls[:, 2], 0)[:, None]
    return np.broadcast_to(f, (len(points),) + f.shape)


def light_dirs(n, seed, eye, n_world):
    rng = np.random.default_rng(seed)
    # around the mirror direction (where the anisotropic highlight is) plus random ones
    r = 2 * (eye @ n_world) * n_world - eye
    a = r + rng.normal(0, 0.25, (n, 3))
    b = rng.normal(size=(n, 3))
    l = np.concatenate([a, b])
    l /= np.linalg.norm(l, axis=1)[:, None]
    return l[l @ n_world > 0.05]


@pytest.mark.parametrize("tilt", [0.0, 0.3])
def test_tangent_rotation_equals_lobe_rotation(variant, tmp_path, tilt):
    m = T.example_material(isotropic=False)
    js = str(tmp_path / "m_lobes.json")
    T.write_lobes_json(js, m)
    m90 = rotated(m, lambda c: (-c[1], c[0], c[2]))  # lobes turned by +90 degrees about z
    js90 = str(tmp_path / "m90_lobes.json")
    T.write_lobes_json(js90, m90)
    mirror = rotated(m, lambda c: (c[0], -c[1], c[2]))
    jsm = str(tmp_path / "mirror_lobes.json")
    T.write_lobes_json(jsm, mirror)

    n_world = np.array([tilt, 0.0, 1.0]) / math.hypot(tilt, 1.0)
    eye = np.array([0.5, 0.35, 0.8])
    eye /= np.linalg.norm(eye)
    pts = [(0.1, 0.2, 0.0), (-0.4, 0.3, 0.0), (0.5, -0.6, 0.0)]
    lights = light_dirs(60 if variant.startswith("scalar") else 400, 3, eye, n_world)
    k = 1e-5

    # tangent +x (with a component along n that Gram-Schmidt removes)
    a = eval_on_mesh(quad_scene(str(tmp_path), "a", js, (1.0, 0.0, 0.4), 1.0, tilt), pts, eye, lights)
    ra = reference(m, pts, eye, lights, tilt, (1.0, 0.0, 0.4))
    assert np.max(np.abs(a - ra)) <= k * ra.max()

    # tangent turned by +90 degrees about n: the frame's x is the old y
    x90 = np.cross(n_world, np.array([1.0, 0.0, 0.0]) - n_world * n_world[0])
    b = eval_on_mesh(quad_scene(str(tmp_path), "b", js, x90, 1.0, tilt), pts, eye, lights)
    rb = reference(m, pts, eye, lights, tilt, x90)
    assert np.max(np.abs(b - rb)) <= k * rb.max()
    # ... which is the original tangent with the lobes turned by +90 degrees about z
    c = eval_on_mesh(quad_scene(str(tmp_path), "c", js90, (1.0, 0.0, 0.4), 1.0, tilt), pts, eye, lights)
    assert np.max(np.abs(b - c)) <= 1e-4 * c.max()
    assert np.max(np.abs(a - b)) > 0.1 * a.max()  # the turn matters (anisotropic material)

    # negative handedness mirrors y
    d = eval_on_mesh(quad_scene(str(tmp_path), "d", js, (1.0, 0.0, 0.4), -1.0, tilt), pts, eye, lights)
    rm = eval_on_mesh(quad_scene(str(tmp_path), "e", jsm, (1.0, 0.0, 0.4), 1.0, tilt), pts, eye, lights)
    assert np.max(np.abs(d - rm)) <= 1e-4 * rm.max()
    assert np.max(np.abs(a - d)) > 0.05 * a.max()


def test_isotropic_material_ignores_the_tangent(variant, tmp_path):
    m = T.example_material(isotropic=True)
    js = str(tmp_path / "iso_lobes.json")
    T.write_lobes_json(js, m)
    eye = np.array([0.3, -0.5, 0.8])
    eye /= np.linalg.norm(eye)
    lights = light_dirs(40, 4, eye, np.array([0.0, 0.0, 1.0]))
    pts = [(0.1, 0.2, 0.0)]
    a = eval_on_mesh(quad_scene(str(tmp_path), "ia", js, (1.0, 0.0, 0.0)), pts, eye, lights)
    b = eval_on_mesh(quad_scene(str(tmp_path), "ib", js, (0.0, 1.0, 0.0), -1.0), pts, eye, lights)
    np.testing.assert_allclose(a, b, rtol=1e-5, atol=1e-6 * a.max())


def test_render_tangent_rotation_equals_lobe_rotation(fast_variant, tmp_path):
    """The same statement through the integrator: a quad under a bright spot of environment,
    rendered with the tangent attribute turned by 90 degrees about n, matches the render with the
    lobes turned by 90 degrees (to noise), and differs clearly from the unturned render."""
    jit = fast_variant.startswith("llvm")
    w, h, spp = (48, 36, 256) if jit else (16, 12, 32)
    m = T.example_material(isotropic=False, rho_d=(0.05, 0.05, 0.05))
    m90 = rotated(m, lambda c: (-c[1], c[0], c[2]))
    # environment (Mitsuba orientation): dim sky plus a bright spot
    he, we = 64, 128
    th = ((np.arange(he) / (he - 1)) * np.pi)[:, None]
    ph = ((np.arange(we) + 0.5) / we * 2 * np.pi)[None, :]
    d = np.stack([np.sin(th) * np.sin(ph), np.cos(th) + 0 * ph, -np.sin(th) * np.cos(ph)], -1)
    spot = np.array([-0.3, 0.55, 0.78])
    spot /= np.linalg.norm(spot)
    env = 0.1 + 30 * np.exp(-40 * (1 - d @ spot))[..., None] * np.ones(3)
    v, n, f, uv, _, _ = T.quad(2.0)
    imgs = {}
    for key, mat, tangent in [("ref", m, (1.0, 0.0, 0.0)), ("turned", m, (0.0, 1.0, 0.0)),
                              ("lobes", m90, (1.0, 0.0, 0.0))]:
        folder = str(tmp_path / key)
        os.makedirs(folder)
        T.write_ply(os.path.join(folder, "q_mesh.ply"), v, n, f, uv, np.tile(tangent, (4, 1)))
        T.write_env_exr(os.path.join(folder, "q_env.exr"), env)
        T.write_lobes_json(os.path.join(folder, "q_lobes.json"), mat)
        xml = os.path.join(folder, "q_mitsuba.xml")
        with open(xml, "w") as fh:
            fh.write(T.scene_xml("q", eye=(0.4, -0.9, 2.2), target=(0, 0, 0), up=(0, 0, 1), width=w, height=h,
                                 spp=spp, ray_offset=3e-4, near=0.5, far=10, material_file="q_lobes.json"))
        scene = mi.load_file(xml)
        imgs[key] = [np.array(mi.render(scene, seed=s), dtype=float) for s in (1, 2)]
    mask = imgs["ref"][0][..., 3] == 1
    assert mask.mean() > 0.5
    lum = lambda a: (a[..., :3] @ [0.2126, 0.7152, 0.0722])[mask]  # noqa: E731
    noise = np.sqrt(np.mean((lum(imgs["turned"][0]) - lum(imgs["turned"][1])) ** 2))
    same = np.sqrt(np.mean((lum(imgs["turned"][0]) - lum(imgs["lobes"][1])) ** 2))
    differ = np.sqrt(np.mean((lum(imgs["turned"][0]) - lum(imgs["ref"][1])) ** 2))
    print(f"\n[{fast_variant}] noise {noise:.4g} turned-vs-lobes {same:.4g} turned-vs-unturned {differ:.4g}")
    assert same < 1.3 * noise, (same, noise)
    assert differ > 3 * noise, (differ, noise)
