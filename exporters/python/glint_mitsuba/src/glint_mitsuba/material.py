"""glint materials as numpy data: reading ``<name>_ph.exr`` and ``<name>_lobes.json``, tabulating the
exact lobe sum, and a float64 reference of f_r (docs/conventions.md §1, §3). No Mitsuba here."""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field, replace
from typing import Optional

import numpy as np

from . import lobes as L


class MaterialError(ValueError):
    """A material file that cannot be read or does not follow docs/conventions.md."""


@dataclass
class Material:
    """One glint material.

    ``table`` (R x R x 3 float32, row y = v, column x = u) is p(h) on the hemi-octahedral grid;
    ``centres`` (J x 3) and ``coefficients`` (3 x J) are the exact lobes. A material read from the
    EXR has only the table; one read from the JSON has only the lobes (importance sampling tabulates
    them, see :func:`eye_conditioned_weights`).
    """

    lam: float
    isotropic: bool
    f0: float
    rho_d: np.ndarray
    centres: Optional[np.ndarray] = None
    coefficients: Optional[np.ndarray] = None
    table: Optional[np.ndarray] = None
    source: str = ""
    specular: bool = True  # False: the Lambertian copy (rho_d only)
    extra: dict = field(default_factory=dict)

    @property
    def exact(self) -> bool:
        return self.centres is not None

    def lambertian(self, rho_d=None) -> "Material":
        """The Lambertian copy: same (or the given) rho_d, no specular term."""
        rho = self.rho_d if rho_d is None else _rgb(rho_d, "rho_d_override")
        return replace(self, rho_d=rho, specular=False)

    # --- p(h) -------------------------------------------------------------------------------
    def p(self, hx, hy, hz):
        """p(h) per channel (array ... x 3), float64: exact lobes if present, else the table."""
        if not self.specular:
            return np.zeros(np.shape(hx) + (3,))
        if self.exact:
            return np.stack(L.p_of_h(np.asarray(hx, float), np.asarray(hy, float), np.asarray(hz, float),
                                     self.centres, self.coefficients, self.lam, self.isotropic, L.NP), -1)
        u, v = L.hemi_oct_encode(np.asarray(hx, float), np.asarray(hy, float), np.asarray(hz, float))
        return table_lookup(self.table, u, v)

    def f_r(self, wi, wo):
        """f_r(wi, wo) (no cosine) per channel, float64 reference of §1; wi, wo arrays (..., 3)
        in the local frame, wi towards the light, wo towards the eye."""
        wi = np.asarray(wi, float)
        wo = np.asarray(wo, float)
        k1 = wi[..., 2]
        k2 = wo[..., 2]
        diff = np.broadcast_to(self.rho_d / math.pi, k1.shape + (3,)).copy()
        out = np.where((k1 > 0)[..., None], diff, 0.0)
        both = (k1 > 0) & (k2 > 0)
        if self.specular and np.any(both):
            a = wi[both]
            b = wo[both]
            h = np.stack(L.half_vector(a.T, b.T), -1)
            s = L.specular_factor(a.T, b.T, self.f0)
            out[both] += self.p(h[:, 0], h[:, 1], h[:, 2]) * s[:, None]
        return out


def _rgb(value, what) -> np.ndarray:
    a = np.asarray(value, dtype=float).reshape(-1)
    if a.size == 1:
        a = np.repeat(a, 3)
    if a.size != 3 or not np.all(np.isfinite(a)) or np.any(a < 0):
        raise MaterialError(f"{what} must be one or three finite values >= 0, got {value!r}")
    return a


# ------------------------------------------------------------------------------------------------
# Table maths (numpy)


def texel_grid(resolution: int):
    """(u, v) of every texel, arrays R x R indexed [y, x] (corner-aligned)."""
    t = np.arange(resolution, dtype=float) / (resolution - 1)
    u, v = np.meshgrid(t, t)  # u varies along x (columns), v along y (rows)
    return u, v


def tabulate(material: Material, resolution: int = 512) -> np.ndarray:
    """p(h) at the texels of an R x R hemi-octahedral table (float32, [y, x, channel])."""
    if resolution < 2:
        raise MaterialError("table resolution must be >= 2")
    u, v = texel_grid(resolution)
    hx, hy, hz = L.hemi_oct_decode(u, v)
    return material.p(hx, hy, hz).astype(np.float32)


def table_lookup(table: np.ndarray, u, v) -> np.ndarray:
    """Bilinear lookup of a corner-aligned table at (u, v) (arrays), float64, shape (..., 3)."""
    r = table.shape[0]
    fx = np.clip(np.asarray(u, float), 0.0, 1.0) * (r - 1)
    fy = np.clip(np.asarray(v, float), 0.0, 1.0) * (r - 1)
    x0 = np.clip(np.floor(fx).astype(np.int64), 0, r - 2)
    y0 = np.clip(np.floor(fy).astype(np.int64), 0, r - 2)
    tx = (fx - x0)[..., None]
    ty = (fy - y0)[..., None]
    t = table.astype(float)
    return ((1 - ty) * ((1 - tx) * t[y0, x0] + tx * t[y0, x0 + 1])
            + ty * ((1 - tx) * t[y0 + 1, x0] + tx * t[y0 + 1, x0 + 1]))


def trapezoid_weights(r: int) -> np.ndarray:
    """Trapezoid-rule area weights of the corner-aligned R x R grid on [0, 1]^2."""
    w = np.full((r, r), 1.0 / (r - 1) ** 2)
    w[0, :] *= 0.5
    w[-1, :] *= 0.5
    w[:, 0] *= 0.5
    w[:, -1] *= 0.5
    return w


def eye_conditioned_weights(material: Material, resolution: int, thetas, phis, floor: float = 1e-5):
    """Half-vector sampling weights given the eye direction e = (sin t cos f, sin t sin f, cos t).

    For each eye, on the corner-aligned (u, v) grid of h: the specular ``f_r cos`` of the light
    direction l = 2 (e.h) h - e, expressed per unit (u, v) area,
    ``w = lum(p(h)) F(c) k1 / (4 (k1 + k2 - k1 k2)) * 4 c * d omega/du dv``, c = e.h, k1 = l.z
    (0 where k1 <= 0 or c <= 0), floored at ``floor`` x the slice's maximum so that every h keeps
    a positive density. Returns ``(weights [len(phis), len(thetas), R, R] float32, albedo
    [len(phis), len(thetas)])`` where albedo is the luminance specular albedo (unfloored)."""
    r = int(resolution)
    u, v = texel_grid(r)
    hx, hy, hz = L.hemi_oct_decode(u, v)
    plum = material.p(hx, hy, hz) @ np.asarray(L.LUMINANCE)
    base = plum * L.hemi_oct_jacobian(u, v)
    area = trapezoid_weights(r)
    thetas = np.asarray(thetas, float)
    phis = np.asarray(phis, float)
    out = np.empty((len(phis), len(thetas), r, r), np.float32)
    albedo = np.empty((len(phis), len(thetas)))
    for i, f in enumerate(phis):
        for j, t in enumerate(thetas):
            e = (math.sin(t) * math.cos(f), math.sin(t) * math.sin(f), math.cos(t))
            c = hx * e[0] + hy * e[1] + hz * e[2]
            k1 = 2 * c * hz - e[2]
            k2 = e[2]
            ok = (k1 > 0) & (c > 0)
            den = np.where(ok, 4 * (k1 + k2 - k1 * k2), 1.0)
            val = np.where(ok, base * L.schlick(c, material.f0) * k1 / den * 4 * c, 0.0)
            albedo[i, j] = float(np.sum(val * area))
            m = float(val.max())
            out[i, j] = np.maximum(val, floor * m) if m > 0 else 1.0
    return out, albedo


def specular_albedo_normal(table: np.ndarray, f0: float) -> np.ndarray:
    """Specular albedo (per channel) for the eye on the normal, by quadrature over the table:
    wo = n, wi = 2 h.z h - n, k1 = 2 h.z^2 - 1, s = F(h.z)/4, d wi = 4 h.z d h."""
    r = table.shape[0]
    u, v = texel_grid(r)
    hx, hy, hz = L.hemi_oct_decode(u, v)
    jac = L.hemi_oct_jacobian(u, v)
    w = trapezoid_weights(r)
    k1 = 2 * hz * hz - 1
    integrand = np.where(k1 > 0, L.schlick(hz, f0) / 4 * k1 * 4 * hz * jac * w, 0.0)
    return np.einsum("yx,yxc->c", integrand, table.astype(float))


# ------------------------------------------------------------------------------------------------
# Files


def load_material(path: str) -> Material:
    """Reads ``<name>_ph.exr`` (table + header scalars) or ``<name>_lobes.json`` (exact lobes)."""
    ext = os.path.splitext(path)[1].lower()
    if ext == ".exr":
        return read_ph_exr(path)
    if ext == ".json":
        return read_lobes_json(path)
    raise MaterialError(f"{path}: expected a glint table '<name>_ph.exr' or lobes '<name>_lobes.json'")


def _scalar(header, key, path):
    if key not in header:
        raise MaterialError(f"{path}: header attribute {key} is missing")
    try:
        return float(np.asarray(header[key], dtype=float).reshape(-1)[0])
    except (TypeError, ValueError, IndexError) as e:
        raise MaterialError(f"{path}: header attribute {key} is not a number") from e


def read_ph_exr(path: str) -> Material:
    import OpenEXR

    if not os.path.isfile(path):
        raise MaterialError(f"{path}: no such file")
    try:
        f = OpenEXR.File(path, separate_channels=True)
        header = f.header()
        channels = f.channels()
    except Exception as e:  # OpenEXR raises plain exceptions
        raise MaterialError(f"{path}: cannot read EXR: {e}") from e
    missing = [c for c in "RGB" if c not in channels]
    if missing:
        raise MaterialError(f"{path}: channels {missing} missing (expected an RGB p(h) table)")
    table = np.stack([np.asarray(channels[c].pixels, dtype=np.float32) for c in "RGB"], -1)
    if table.ndim != 3 or table.shape[0] != table.shape[1] or table.shape[0] < 2:
        raise MaterialError(f"{path}: the table must be R x R (R >= 2), got {table.shape[:2]}")
    if not np.all(np.isfinite(table)) or np.any(table < 0):
        raise MaterialError(f"{path}: the table holds negative or non-finite values")
    param = str(header.get("glint.parameterisation", "hemi-octahedral"))
    if not param.startswith("hemi-octahedral"):
        raise MaterialError(f"{path}: parameterisation {param.split(':')[0]!r} is not hemi-octahedral")
    if all(f"glint.rho_d_{c}" in header for c in "rgb"):
        rho_d = np.array([_scalar(header, f"glint.rho_d_{c}", path) for c in "rgb"])
    elif "glint.rho_d" in header:
        rho_d = _rgb(np.asarray(header["glint.rho_d"], dtype=float), f"{path}: glint.rho_d")
    else:
        raise MaterialError(f"{path}: neither glint.rho_d_r/g/b nor glint.rho_d in the header")
    lam = _scalar(header, "glint.lambda", path)
    f0 = _scalar(header, "glint.f0", path)
    iso = bool(int(_scalar(header, "glint.isotropic", path))) if "glint.isotropic" in header else False
    return Material(lam=lam, isotropic=iso, f0=f0, rho_d=_rgb(rho_d, f"{path}: rho_d"), table=table,
                    source=path, extra={k: header[k] for k in header if str(k).startswith("glint.")})


def read_lobes_json(path: str) -> Material:
    try:
        with open(path, encoding="utf-8") as fh:
            d = json.load(fh)
    except (OSError, json.JSONDecodeError) as e:
        raise MaterialError(f"{path}: cannot read lobes JSON: {e}") from e
    return material_from_dict(d, path)


def material_from_dict(d: dict, where: str = "lobes") -> Material:
    """The lobe JSON of an export (`<name>_lobes.json`, the glTF extras' object) or glint's material
    JSON (`glint fit`'s output, whose `layout` is an object such as {"kind": "isotropic", "count": 24}
    and which has no `isotropic` key)."""
    if "isotropic" not in d and "layout" in d:
        layout = d["layout"]
        kind = layout.get("kind") if isinstance(layout, dict) else str(layout).split("-")[0]
        d = dict(d, isotropic=(kind == "isotropic"))
    for key in ("lambda", "isotropic", "centres", "coefficients", "rho_d", "f0"):
        if key not in d:
            raise MaterialError(f"{where}: key {key!r} is missing")
    centres = np.asarray(d["centres"], dtype=float).reshape(-1, 3) if len(d["centres"]) else np.zeros((0, 3))
    coeffs = np.asarray(d["coefficients"], dtype=float)
    if coeffs.ndim != 2 or coeffs.shape != (3, len(centres)):
        raise MaterialError(f"{where}: coefficients must be 3 x J with J = {len(centres)} centres, "
                            f"got shape {coeffs.shape}")
    if np.any(coeffs < 0) or not np.all(np.isfinite(coeffs)):
        raise MaterialError(f"{where}: coefficients must be finite and >= 0")
    norms = np.linalg.norm(centres, axis=1)
    if len(centres) and np.max(np.abs(norms - 1)) > 1e-4:
        raise MaterialError(f"{where}: centres must be unit vectors")
    if len(centres):
        centres = centres / norms[:, None]
    lam = float(d["lambda"])
    if not (lam > 0 and math.isfinite(lam)):
        raise MaterialError(f"{where}: lambda must be > 0")
    return Material(lam=lam, isotropic=bool(d["isotropic"]), f0=float(d["f0"]),
                    rho_d=_rgb(d["rho_d"], f"{where}: rho_d"), centres=centres, coefficients=coeffs,
                    source=where)


def material_to_dict(m: Material) -> dict:
    """The lobes JSON keys for a material with exact lobes."""
    if not m.exact:
        raise MaterialError("only a material with exact lobes can be written as lobes JSON")
    return {"lambda": m.lam, "isotropic": m.isotropic, "centres": m.centres.tolist(),
            "coefficients": m.coefficients.tolist(), "rho_d": list(map(float, m.rho_d)), "f0": m.f0}
