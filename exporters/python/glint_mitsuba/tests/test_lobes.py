"""The lobe maths of docs/conventions.md §1 (the plugin's JSON path) against independent checks."""

import math
from decimal import Decimal, getcontext

import numpy as np
import pytest

from glint_mitsuba import lobes as L
from glint_mitsuba.material import table_lookup, tabulate
from glint_mitsuba.testing import example_material

# exp(-x) I0(x) from the power series sum_k (x^2/4)^k / (k!)^2, evaluated in 60-digit decimals.
I0E_TABLE = {
    0.0: 1.0, 0.5: 0.64503527044915007, 1.0: 0.46575960759364044, 2.0: 0.30850832255367104,
    5.0: 0.18354081260932835, 8.0: 0.14343178185685031, 10.0: 0.12783333716342861,
    20.0: 0.089780311884826022, 50.0: 0.056561626647454193, 100.0: 0.039944379299096683,
    300.0: 0.023042558415085462, 700.0: 0.015081295651531358,
}


def i0e_series(x: float) -> float:
    getcontext().prec = 60
    d = Decimal(repr(x))
    q = d * d / 4
    term = s = Decimal(1)
    k = 0
    while True:
        k += 1
        term = term * q / (k * k)
        s += term
        if term < s * Decimal(10) ** -40:
            break
    return float(s * (-d).exp())


def test_i0e_table_and_series_float64():
    xs = np.array(sorted(I0E_TABLE))
    got = L.i0e(xs)
    want = np.array([I0E_TABLE[x] for x in xs])
    np.testing.assert_allclose(got, want, rtol=1e-14, atol=0)
    rng = np.random.default_rng(3)
    for x in np.concatenate([rng.uniform(0, 8, 20), rng.uniform(8, 200, 20), [7.999999, 8.0, 8.000001]]):
        assert abs(L.i0e(np.float64(x)) / i0e_series(float(x)) - 1) < 1e-14


def test_i0e_asymptotic_and_no_overflow():
    # I0e(x) ~ (2 pi x)^(-1/2) (1 + 1/(8x) + 9/(128 x^2) + 225/(3072 x^3)) for large x; I0 itself
    # overflows float64 beyond ~713.
    for x in [1e3, 1e4, 1e6]:
        asym = (1 + 1 / (8 * x) + 9 / (128 * x * x) + 225 / (3072 * x ** 3)) / math.sqrt(2 * math.pi * x)
        assert abs(L.i0e(np.float64(x)) / asym - 1) < 1e-10


def test_i0e_float32_drjit():
    dr = pytest.importorskip("drjit")
    xs = np.concatenate([np.linspace(0, 8, 401), np.geomspace(8, 5000, 400)])
    got = np.array(L.i0e(dr.scalar.ArrayXf(xs.astype(np.float32)), L.drjit_ops()))
    want = L.i0e(xs.astype(np.float32).astype(np.float64))
    assert np.max(np.abs(got / want - 1)) < 1e-6


def ring_by_quadrature(h, xi, lam, n=4096):
    """(1/2pi) int exp(2 lambda (h . Rz(phi) xi - 1)) dphi by the periodic trapezoid rule."""
    phi = 2 * np.pi * np.arange(n) / n
    c, s = np.cos(phi), np.sin(phi)
    rx = c * xi[0] - s * xi[1]
    ry = s * xi[0] + c * xi[1]
    dots = h[:, :1] * rx + h[:, 1:2] * ry + h[:, 2:3] * xi[2]
    return np.exp(2 * lam * (dots - 1)).mean(1)


def random_hemisphere(n, seed):
    h = np.random.default_rng(seed).normal(size=(n, 3))
    h[:, 2] = np.abs(h[:, 2])
    return h / np.linalg.norm(h, axis=1)[:, None]


@pytest.mark.parametrize("lam", [5.0, 81.06, 400.0])
def test_ring_lobe_is_azimuthal_average_of_point_lobe(lam):
    h = random_hemisphere(300, 1)
    # also points near the lobe's ring, where the values are largest
    for j in range(0, 20, 3):
        th_j = (math.pi / 2) * j / 20
        xi = np.array([math.sin(th_j), 0.0, math.cos(th_j)])
        th = th_j + np.linspace(-0.2, 0.2, 21)
        near = np.stack([np.sin(th) * 0.6, np.sin(th) * 0.8, np.cos(th)], 1)
        near = near[near[:, 2] >= 0]
        hh = np.concatenate([h, near])
        ring = L.ring_lobe(hh[:, 0], hh[:, 1], hh[:, 2], xi, lam)
        quad = ring_by_quadrature(hh, xi, lam)
        peak = max(float(ring.max()), 1e-300)
        assert np.max(np.abs(ring - quad)) <= 1e-9 * peak + 1e-300
        big = quad > 1e-200
        np.testing.assert_allclose(ring[big], quad[big], rtol=1e-6)


def test_point_lobe_matches_formula():
    h = random_hemisphere(1000, 2)
    xi = np.array([0.3, -0.2, 0.9])
    xi /= np.linalg.norm(xi)
    lam = 81.06
    np.testing.assert_allclose(L.point_lobe(h[:, 0], h[:, 1], h[:, 2], xi, lam),
                               np.exp(2 * lam * (h @ xi - 1)), rtol=1e-12)


@pytest.mark.parametrize("isotropic", [False, True])
def test_float32_drjit_lobe_sum_matches_float64(isotropic):
    dr = pytest.importorskip("drjit")
    m = example_material(isotropic=isotropic)
    h = random_hemisphere(20000, 4)
    ref = np.stack(L.p_of_h(h[:, 0], h[:, 1], h[:, 2], m.centres, m.coefficients, m.lam, isotropic), -1)
    hf = [dr.scalar.ArrayXf(h[:, k].astype(np.float32)) for k in range(3)]
    got = np.stack([np.array(c) for c in L.p_of_h(*hf, m.centres, m.coefficients, m.lam, isotropic,
                                                   L.drjit_ops())], -1)
    # float32 rounding of h itself moves p by up to |grad p| * 6e-8
    assert np.max(np.abs(got - ref)) <= 3e-6 * ref.max()


def test_hemi_octahedral_map():
    u, v = np.meshgrid(np.linspace(0, 1, 65), np.linspace(0, 1, 65))
    h = np.stack(L.hemi_oct_decode(u, v), -1)
    np.testing.assert_allclose(np.linalg.norm(h, axis=-1), 1, atol=1e-12)
    assert h[..., 2].min() >= 0
    uu, vv = L.hemi_oct_encode(h[..., 0], h[..., 1], h[..., 2])
    np.testing.assert_allclose(uu, u, atol=1e-12)
    np.testing.assert_allclose(vv, v, atol=1e-12)
    # landmarks of §3: +x at u = v = 1, +y at u = 1, v = 0, the normal at the centre
    np.testing.assert_allclose(L.hemi_oct_decode(1.0, 1.0), (1, 0, 0), atol=1e-12)
    np.testing.assert_allclose(L.hemi_oct_decode(1.0, 0.0), (0, 1, 0), atol=1e-12)
    np.testing.assert_allclose(L.hemi_oct_decode(0.5, 0.5), (0, 0, 1), atol=1e-12)


def test_hemi_octahedral_jacobian_integrates_to_2pi_and_matches_finite_differences():
    n = 1024
    t = (np.arange(n) + 0.5) / n
    u, v = np.meshgrid(t, t)
    assert abs(L.hemi_oct_jacobian(u, v).mean() - 2 * np.pi) < 1e-4
    rng = np.random.default_rng(0)
    for u0, v0 in rng.uniform(0.02, 0.98, (20, 2)):
        e = 1e-6
        h = lambda a, b: np.array(L.hemi_oct_decode(a, b))  # noqa: E731
        du = (h(u0 + e, v0) - h(u0 - e, v0)) / (2 * e)
        dv = (h(u0, v0 + e) - h(u0, v0 - e)) / (2 * e)
        assert abs(np.linalg.norm(np.cross(du, dv)) / L.hemi_oct_jacobian(u0, v0) - 1) < 1e-5


@pytest.mark.parametrize("isotropic", [False, True])
def test_table_at_512_is_within_1e3_of_peak_numpy(isotropic):
    m = example_material(isotropic=isotropic)
    table = tabulate(m, 512)
    h = random_hemisphere(200000, 7)
    exact = m.p(h[:, 0], h[:, 1], h[:, 2])
    u, v = L.hemi_oct_encode(h[:, 0], h[:, 1], h[:, 2])
    assert np.max(np.abs(table_lookup(table, u, v) - exact)) <= 1e-3 * exact.max()


def test_glint_material_json_is_read_like_the_lobe_json():
    """`glint fit`'s material JSON (layout as an object, no `isotropic` key) gives the same material
    as the export's lobe JSON."""
    from glint_mitsuba.material import material_from_dict

    common = {"lambda": 81.06, "centres": [[0.0, 0.0, 1.0], [0.5, 0.0, 0.8660254037844386]],
              "coefficients": [[1.0, 0.5], [0.8, 0.4], [0.6, 0.3]], "rho_d": [0.2, 0.2, 0.2], "f0": 0.04}
    fit_json = dict(common, layout={"kind": "isotropic", "count": 2}, model="dbrdf-srbf", version=1)
    lobe_json = dict(common, layout="isotropic-2", isotropic=True)
    a, b = material_from_dict(fit_json), material_from_dict(lobe_json)
    assert a.isotropic and b.isotropic
    assert (a.coefficients == b.coefficients).all() and (a.centres == b.centres).all()
    aniso = material_from_dict(dict(common, layout={"kind": "hemicube", "n": 1}))
    assert not aniso.isotropic
