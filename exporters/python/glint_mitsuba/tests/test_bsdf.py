"""The ``glint`` BSDF plugin: eval against the float64 reference of docs/conventions.md §1, the table
path against the exact-lobe path, reciprocity, the silhouette rule, and sample() against pdf()."""

import math
import os

import numpy as np
import pytest

from glint_mitsuba import testing as T
from glint_mitsuba.material import MaterialError, load_material

mi = pytest.importorskip("mitsuba")
dr = pytest.importorskip("drjit")


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """An anisotropic and an isotropic material, each as lobes JSON and as a 512^2 table EXR."""
    d = tmp_path_factory.mktemp("materials")
    out = {}
    for iso in (False, True):
        m = T.example_material(isotropic=iso)
        key = "iso" if iso else "aniso"
        T.write_lobes_json(os.path.join(d, f"{key}_lobes.json"), m)
        T.write_ph_exr(os.path.join(d, f"{key}_ph.exr"), m, 512)
        out[key] = (m, os.path.join(d, f"{key}_lobes.json"), os.path.join(d, f"{key}_ph.exr"))
    return out


def load_bsdf(path, **extra):
    return mi.load_dict({"type": "glint", "filename": str(path), **extra})


def random_pairs(n, seed, below=False):
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(n, 3))
    b = rng.normal(size=(n, 3))
    if not below:
        a[:, 2] = np.abs(a[:, 2])
        b[:, 2] = np.abs(b[:, 2])
    a /= np.linalg.norm(a, axis=1)[:, None]
    b /= np.linalg.norm(b, axis=1)[:, None]
    return a, b


def near_specular_pairs(n, seed):
    """Eye directions and light directions close to the highlight (where p is large)."""
    rng = np.random.default_rng(seed)
    e, _ = random_pairs(n, seed)
    h = np.stack([rng.normal(0, 0.15, n), rng.normal(0, 0.1, n), np.ones(n)], 1)
    h /= np.linalg.norm(h, axis=1)[:, None]
    l = 2 * np.sum(e * h, 1)[:, None] * h - e
    keep = l[:, 2] > 0.02
    return e[keep], l[keep]


def sizes(variant, jit, scalar):
    return jit if variant.startswith("llvm") else scalar


@pytest.mark.parametrize("key", ["aniso", "iso"])
def test_json_eval_matches_float64_reference(variant, files, key):
    m, js, _ = files[key]
    bsdf = load_bsdf(js)
    n = sizes(variant, 20000, 400)
    e1, l1 = random_pairs(n, 1, below=True)
    e2, l2 = near_specular_pairs(n, 2)
    e, l = np.concatenate([e1, e2]), np.concatenate([l1, l2])
    # the plugin sees float32 directions: give the float64 reference the same ones
    e, l = e.astype(np.float32).astype(float), l.astype(np.float32).astype(float)
    f, _ = bsdf_eval(bsdf, e, l)
    ref = m.f_r(l, e) * np.maximum(l[:, 2], 0)[:, None]
    assert np.max(np.abs(f - ref)) <= 1e-5 * ref.max()
    # zero with the light below the horizon; diffuse only with the eye below (silhouette rule)
    assert np.all(f[l[:, 2] <= 0] == 0)
    sil = (l[:, 2] > 0) & (e[:, 2] <= 0)
    assert sil.any()
    np.testing.assert_allclose(f[sil], (m.rho_d / math.pi)[None, :] * l[sil, 2:3], rtol=1e-5)


def bsdf_eval(bsdf, e, l):
    return T.bsdf_eval_pdf(bsdf, e, l)


@pytest.mark.parametrize("key", ["aniso", "iso"])
def test_table_path_matches_exact_lobes_within_1e3_of_peak(variant, files, key):
    m, js, exr = files[key]
    n = sizes(variant, 40000, 400)
    e1, l1 = random_pairs(n, 3)
    e2, l2 = near_specular_pairs(n, 4)
    e, l = np.concatenate([e1, e2]), np.concatenate([l1, l2])
    f_json, _ = bsdf_eval(load_bsdf(js), e, l)
    f_exr, _ = bsdf_eval(load_bsdf(exr), e, l)
    assert np.max(np.abs(f_exr - f_json)) <= 1e-3 * f_json.max()


@pytest.mark.parametrize("key", ["aniso", "iso"])
def test_reciprocity(variant, files, key):
    _, js, exr = files[key]
    n = sizes(variant, 5000, 200)
    a, b = random_pairs(n, 5)
    ok = (a[:, 2] > 1e-3) & (b[:, 2] > 1e-3)
    a, b = a[ok], b[ok]
    for path in (js, exr):
        bsdf = load_bsdf(path)
        fab, _ = bsdf_eval(bsdf, a, b)
        fba, _ = bsdf_eval(bsdf, b, a)
        fab /= b[:, 2:3]
        fba /= a[:, 2:3]
        assert np.max(np.abs(fab - fba)) <= 1e-5 * fab.max()


def test_header_scalars_and_lambertian_copies(variant, files, tmp_path):
    m, js, exr = files["iso"]
    mat = load_material(exr)
    assert mat.isotropic and mat.lam == pytest.approx(m.lam) and mat.f0 == pytest.approx(m.f0)
    np.testing.assert_allclose(mat.rho_d, m.rho_d, rtol=1e-6)
    e, l = random_pairs(50, 6)
    for path in (js, exr):
        f, p = bsdf_eval(load_bsdf(path, lambertian=True), e, l)
        np.testing.assert_allclose(f, (m.rho_d / math.pi)[None, :] * l[:, 2:3], rtol=1e-5)
        np.testing.assert_allclose(p, l[:, 2] / math.pi, rtol=1e-5)
        f, _ = bsdf_eval(load_bsdf(path, rho_d_override=0.5), e, l)
        np.testing.assert_allclose(f, 0.5 / math.pi * np.repeat(l[:, 2:3], 3, 1), rtol=1e-5)
    # the v3d glint.rho_d alone (no float scalars) is enough
    import OpenEXR

    f = OpenEXR.File(exr)
    h = dict(f.header())
    for c in "rgb":
        h.pop(f"glint.rho_d_{c}")
    ch = {c: np.ascontiguousarray(np.asarray(f.channels()["RGB"].pixels)[:, :, k]) for k, c in enumerate("RGB")}
    h = {k: v for k, v in h.items() if k.startswith("glint.")}
    h.update(compression=OpenEXR.NO_COMPRESSION, type=OpenEXR.scanlineimage)
    p = str(tmp_path / "v3d_ph.exr")
    OpenEXR.File(h, ch).write(p)
    np.testing.assert_allclose(load_material(p).rho_d, m.rho_d, rtol=1e-12)
    with pytest.raises(MaterialError):
        load_material(str(tmp_path / "missing_ph.exr"))
    with pytest.raises(Exception, match="filename"):
        mi.load_dict({"type": "glint"})


EYES = [(0.0, 0.0), (0.6, 0.3), (1.2, 2.0), (1.5, -1.0)]


@pytest.mark.parametrize("key,which", [("aniso", 1), ("iso", 2)])
def test_pdf_integrates_to_sampled_mass_and_albedo_by_sampling(fast_variant, files, key, which):
    """∫ pdf over the sphere equals the fraction of sample() calls that return a direction (the
    rest are reflections below the horizon), and E[weight] = the albedo by quadrature (1 %)."""
    m, js, exr = files[key]
    bsdf = load_bsdf(js if which == 1 else exr)
    jit = fast_variant.startswith("llvm")
    nq = 512 if jit else 96
    ns = 1 << 20 if jit else 6000
    dirs, w = T.hemisphere_quadrature(nq)
    rng = np.random.default_rng(11)
    for th, ph in EYES if jit else EYES[:2]:
        e = np.array([math.sin(th) * math.cos(ph), math.sin(th) * math.sin(ph), math.cos(th)])
        f, p = bsdf_eval(bsdf, np.tile(e, (len(dirs), 1)), dirs)
        integral = float(np.sum(p * w))
        albedo = (f * w[:, None]).sum(0)
        wo, pdf, weight = T.bsdf_sample(bsdf, e, rng.random(ns), rng.random((ns, 2)))
        valid = pdf > 0
        frac = valid.mean()
        assert abs(integral - frac) <= 5 * math.sqrt(frac * (1 - frac) / ns) + (2e-3 if jit else 2e-2)
        if th == 0.0:
            assert integral > 0.95
        mc = weight.mean(0)
        sigma = weight.std(0) / math.sqrt(ns)
        assert np.all(np.abs(mc - albedo) <= np.maximum(5 * sigma, 0.0)) or \
            np.all(np.abs(mc / albedo - 1) < 0.01), (mc, albedo, sigma)
        assert np.all(np.abs(mc / albedo - 1) < (0.01 if jit else 0.05))
        # the returned pdf is pdf() at the returned direction
        _, p2 = bsdf_eval(bsdf, np.tile(e, (valid.sum(), 1)), wo[valid])
        np.testing.assert_allclose(pdf[valid], p2, rtol=1e-4)


def test_sample_histogram_chi_square(fast_variant, files):
    """Histogram of sampled light directions on a 16 x 16 hemi-octahedral grid vs pdf() integrated
    over each cell (Pearson chi-square, cells with expected count < 5 pooled)."""
    jit = fast_variant.startswith("llvm")
    _, js, _ = files["aniso"]
    bsdf = load_bsdf(js)
    e = np.array([math.sin(0.7) * math.cos(0.4), math.sin(0.7) * math.sin(0.4), math.cos(0.7)])
    ns = 1 << 20 if jit else 20000
    rng = np.random.default_rng(12)
    wo, pdf, _ = T.bsdf_sample(bsdf, e, rng.random(ns), rng.random((ns, 2)))
    from glint_mitsuba import lobes as L

    cells = 16
    u, v = L.hemi_oct_encode(wo[:, 0], wo[:, 1], wo[:, 2])
    ok = pdf > 0
    iu = np.clip((u[ok] * cells).astype(int), 0, cells - 1)
    iv = np.clip((v[ok] * cells).astype(int), 0, cells - 1)
    observed = np.bincount(iv * cells + iu, minlength=cells * cells).astype(float)
    sub = 24 if jit else 8
    dirs, w = T.hemisphere_quadrature(cells * sub)
    _, p = bsdf_eval(bsdf, np.tile(e, (len(dirs), 1)), dirs)
    expected = (p * w).reshape(cells, sub, cells, sub).sum((1, 3)).reshape(-1) * ns
    order = np.argsort(expected)
    small = np.cumsum(expected[order]) < 5 * 4
    pooled_o = [observed[order][small].sum()] + list(observed[order][~small])
    pooled_e = [expected[order][small].sum()] + list(expected[order][~small])
    pooled_o, pooled_e = np.array(pooled_o), np.array(pooled_e)
    keep = pooled_e > 0
    chi2 = np.sum((pooled_o[keep] - pooled_e[keep]) ** 2 / pooled_e[keep])
    dof = keep.sum() - 1
    # the cell integrals have a quadrature error: allow it on top of the statistical spread
    assert chi2 < dof + 6 * math.sqrt(2 * dof) + (0.002 if jit else 0.02) ** 2 * ns, (chi2, dof)
