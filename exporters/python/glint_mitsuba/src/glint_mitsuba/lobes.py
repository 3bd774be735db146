"""glint's BRDF maths (docs/conventions.md §1 and §3), written once for two array back ends.

Every function takes an ``ops`` argument: :data:`NP` (numpy, float64: tabulation, tests) or
:data:`DR` (Dr.Jit: the Mitsuba plugin, any variant; Python floats in ``scalar_rgb``, JIT arrays in
``llvm_ad_rgb``). Only arithmetic, ``sqrt``, ``exp``, ``select``, ``maximum``, ``minimum`` and
``abs`` are used, so the same expressions serve both.

Numerics (the plugin runs in float32):

- point lobe  ``exp(2 lambda (h.xi - 1)) = exp(-lambda |h - xi|^2)`` for unit h, xi (no cancellation
  in ``h.xi - 1`` near the peak);
- ring lobe   ``exp(2 lambda (cos(th - tj) - 1)) I0e(2 lambda sin th sin tj)`` with
  ``2 (cos(th - tj) - 1) = -((sin th - sin tj)^2 + (cos th - cos tj)^2)`` and
  ``sin th = sqrt(hx^2 + hy^2)``;
- ``I0e(x) = exp(-x) I0(x)`` by the Cephes Chebyshev expansions (``i0e.c``, public domain; the same
  coefficients numpy's ``np.i0`` uses): relative error ~1e-16 in float64, ~1e-7 in float32.
"""

from __future__ import annotations

import math

import numpy as np

# Cephes i0e: Chebyshev coefficients for exp(-x) I0(x) on [0, 8] (argument x/2 - 2) ...
_I0E_A = (
    -4.41534164647933937950e-18, 3.33079451882223809783e-17, -2.43127984654795469359e-16,
    1.71539128555513303061e-15, -1.16853328779934516808e-14, 7.67618549860493561688e-14,
    -4.85644678311192946090e-13, 2.95505266312963983461e-12, -1.72682629144155570723e-11,
    9.67580903537323691224e-11, -5.18979560163526290666e-10, 2.65982372468238665035e-9,
    -1.30002500998624804212e-8, 6.04699502254191894932e-8, -2.67079385394061173391e-7,
    1.11738753912010371815e-6, -4.41673835845875056359e-6, 1.64484480707288970893e-5,
    -5.75419501008210370398e-5, 1.88502885095841655729e-4, -5.76375574538582365885e-4,
    1.63947561694133579842e-3, -4.32430999505057594430e-3, 1.05464603945949983183e-2,
    -2.37374148058994688156e-2, 4.93052842396707084878e-2, -9.49010970480476444210e-2,
    1.71620901522208775349e-1, -3.04682672343198398683e-1, 6.76795274409476084995e-1,
)
# ... and for sqrt(x) exp(-x) I0(x) on [8, inf) (argument 32/x - 2).
_I0E_B = (
    -7.23318048787475395456e-18, -4.83050448594418207126e-18, 4.46562142029675999901e-17,
    3.46122286769746109310e-17, -2.82762398051658348494e-16, -3.42548561967721913462e-16,
    1.77256013305652638360e-15, 3.81168066935262242075e-15, -9.55484669882830764870e-15,
    -4.15056934728722208663e-14, 1.54008621752140982691e-14, 3.85277838274214270114e-13,
    7.18012445138366623367e-13, -1.79417853150680611778e-12, -1.32158118404477131188e-11,
    -3.14991652796324136454e-11, 1.18891471078464383424e-11, 4.94060238822496958910e-10,
    3.39623202570838634515e-9, 2.26666899049817806459e-8, 2.04891858946906374183e-7,
    2.89137052083475648297e-6, 6.88975834691682398426e-5, 3.36911647825569408990e-3,
    8.04490411014108831608e-1,
)

LUMINANCE = (0.2126, 0.7152, 0.0722)


class _NumpyOps:
    name = "numpy"
    sqrt = staticmethod(np.sqrt)
    exp = staticmethod(np.exp)
    abs = staticmethod(np.abs)
    maximum = staticmethod(np.maximum)
    minimum = staticmethod(np.minimum)

    @staticmethod
    def select(cond, a, b):
        return np.where(cond, a, b)


class _DrjitOps:
    name = "drjit"

    def __init__(self):
        import drjit as dr

        self.sqrt = dr.sqrt
        self.exp = dr.exp
        self.abs = dr.abs
        self.maximum = dr.maximum
        self.minimum = dr.minimum
        self.select = dr.select


NP = _NumpyOps()
_DR = None


def drjit_ops():
    """The Dr.Jit back end (created on first use, so that numpy-only callers never import drjit)."""
    global _DR
    if _DR is None:
        _DR = _DrjitOps()
    return _DR


def _chbevl(x, coeffs):
    b0 = coeffs[0] + 0.0 * x
    b1 = 0.0 * x
    b2 = 0.0 * x
    for c in coeffs[1:]:
        b2 = b1
        b1 = b0
        b0 = x * b1 - b2 + c
    return 0.5 * (b0 - b2)


def i0e(x, ops=NP):
    """Exponentially scaled modified Bessel function of order 0, ``exp(-|x|) I0(x)``."""
    x = ops.abs(x)
    small = _chbevl(x * 0.5 - 2.0, _I0E_A)
    xl = ops.maximum(x, 8.0)  # keeps the unused branch finite
    large = _chbevl(32.0 / xl - 2.0, _I0E_B) / ops.sqrt(xl)
    return ops.select(x <= 8.0, small, large)


def point_lobe(hx, hy, hz, xi, lam, ops=NP):
    """``exp(2 lambda (h.xi - 1))`` for unit h and unit centre ``xi`` (3 floats)."""
    dx = hx - float(xi[0])
    dy = hy - float(xi[1])
    dz = hz - float(xi[2])
    return ops.exp(-lam * (dx * dx + dy * dy + dz * dz))


def ring_lobe(hx, hy, hz, xi, lam, ops=NP):
    """Point lobe at ``xi`` averaged over the azimuth about z (depends on h.z only)."""
    sj = math.hypot(float(xi[0]), float(xi[1]))
    cj = float(xi[2])
    sh = ops.sqrt(hx * hx + hy * hy)
    ds = sh - sj
    dc = hz - cj
    return ops.exp(-lam * (ds * ds + dc * dc)) * i0e((2.0 * lam * sj) * sh, ops)


def p_of_h(hx, hy, hz, centres, coefficients, lam, isotropic, ops=NP):
    """The lobe sum p(h) per channel: a tuple (R, G, B) of arrays like ``hx``.

    ``centres`` J x 3, ``coefficients`` 3 x J (rows R, G, B). Isotropic layouts use ring lobes.
    """
    lobe = ring_lobe if isotropic else point_lobe
    out = [0.0 * hx, 0.0 * hx, 0.0 * hx]
    for j in range(len(centres)):
        cr, cg, cb = (float(coefficients[k][j]) for k in range(3))
        if cr == 0.0 and cg == 0.0 and cb == 0.0:
            continue
        g = lobe(hx, hy, hz, centres[j], lam, ops)
        out[0] = out[0] + cr * g
        out[1] = out[1] + cg * g
        out[2] = out[2] + cb * g
    return tuple(out)


def schlick(c, f0):
    m = 1.0 - c
    m2 = m * m
    return f0 + (1.0 - f0) * (m2 * m2 * m)


def specular_factor(wi, wo, f0, ops=NP):
    """``s(wi, wo) = F(c) / (4 (k1 + k2 - k1 k2))`` (no p(h), no cosine); wi, wo are (x, y, z)."""
    k1, k2 = wi[2], wo[2]
    cosd = wi[0] * wo[0] + wi[1] * wo[1] + wi[2] * wo[2]
    c = ops.sqrt(ops.maximum((1.0 + cosd) * 0.5, 0.0))
    denom = 4.0 * (k1 + k2 - k1 * k2)
    return schlick(c, f0) / ops.select(denom > 0.0, denom, 1.0)


def half_vector(wi, wo, ops=NP):
    hx, hy, hz = wi[0] + wo[0], wi[1] + wo[1], wi[2] + wo[2]
    n2 = hx * hx + hy * hy + hz * hz
    inv = 1.0 / ops.sqrt(ops.select(n2 > 0.0, n2, 1.0))
    return hx * inv, hy * inv, hz * inv


# ----------------------------------------------------------------------------------------------
# Hemi-octahedral map (§3)


def hemi_oct_decode(u, v, ops=NP):
    """(u, v) in [0, 1]^2 -> unit h (tuple), z >= 0."""
    a = 2.0 * u - 1.0
    b = 2.0 * v - 1.0
    px = (a + b) * 0.5
    py = (a - b) * 0.5
    pz = ops.maximum(1.0 - ops.abs(px) - ops.abs(py), 0.0)
    inv = 1.0 / ops.sqrt(px * px + py * py + pz * pz)
    return px * inv, py * inv, pz * inv


def hemi_oct_encode(hx, hy, hz, ops=NP):
    """Unit h -> (u, v); h.z < 0 is read as the horizon."""
    l1 = ops.abs(hx) + ops.abs(hy) + ops.maximum(hz, 0.0)
    inv = 1.0 / ops.select(l1 > 0.0, l1, 1.0)
    x = hx * inv
    y = hy * inv
    return (x + y + 1.0) * 0.5, (x - y + 1.0) * 0.5


def hemi_oct_jacobian(u, v, ops=NP):
    """Solid angle per unit (u, v) area, ``d omega / du dv = 2 / |P|^3``.

    (u, v) -> (px, py) has |det| = 2; the octahedron face point P = (px, py, 1 - |px| - |py|)
    projects to the sphere with d omega = dpx dpy / |P|^3.
    """
    a = 2.0 * u - 1.0
    b = 2.0 * v - 1.0
    px = (a + b) * 0.5
    py = (a - b) * 0.5
    pz = ops.maximum(1.0 - ops.abs(px) - ops.abs(py), 0.0)
    r2 = px * px + py * py + pz * pz
    return 2.0 / (r2 * ops.sqrt(r2))
