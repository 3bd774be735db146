"""The ``glint`` BSDF for Mitsuba 3 (docs/conventions.md §1-§3).

Mitsuba's convention: ``si.wi`` points to the eye (glint's wo), the argument ``wo`` to the light
(glint's wi); ``eval`` returns ``f_r * max(cos theta_light, 0)``.

The code is vectorised Dr.Jit and runs unchanged in ``scalar_rgb`` and the JIT variants; the class is
built per variant by :func:`make_bsdf_class` (``mi.BSDF`` differs between variants).
"""

from __future__ import annotations

import math
import os

import numpy as np

from . import lobes as L
from .material import Material, MaterialError, eye_conditioned_weights, load_material

INV_PI = 1.0 / math.pi
DEFAULT_SAMPLING_RESOLUTION = 0  # 0: 256 for isotropic materials, 128 for anisotropic ones
N_THETA = 16  # eye polar angles of the sampling slices, 0 .. pi/2
N_PHI = 24  # eye azimuths (anisotropic materials), 0 .. 2 pi


class GlintCore:
    """Variant-specific evaluation and sampling of one material (used by the plugin and the tests).

    All methods take and return vectors in glint's local frame (§2): ``e`` towards the eye, ``l``
    towards the light, as ``mi.Vector3f``.
    """

    def __init__(self, material: Material, sampling_resolution: int = DEFAULT_SAMPLING_RESOLUTION):
        import drjit as dr
        import mitsuba as mi

        self.mi, self.dr = mi, dr
        self.ops = L.drjit_ops()
        self.jit = dr.is_jit_v(mi.Float)
        self.material = material
        self.rho_d = [float(c) for c in material.rho_d]
        self.f0 = float(material.f0)
        self.isotropic = bool(material.isotropic)
        self.exact = material.exact
        has_lobes = (material.exact and material.coefficients.size and material.coefficients.max() > 0) or \
                    (not material.exact and material.table is not None and material.table.max() > 0)
        self.specular = bool(material.specular and has_lobes)
        self.p_spec = 0.0
        if not self.specular:
            return
        if not self.exact:
            table = np.ascontiguousarray(material.table, dtype=np.float32)
            self.res = table.shape[0]
            if self.jit:
                self.flat = mi.Float(table.reshape(-1))
            else:
                self.flat = table.reshape(-1, 3)
        else:
            self.centres = np.asarray(material.centres, float)
            self.coefficients = np.asarray(material.coefficients, float)
        # Half-vector sampling conditioned on the eye direction (theta_e; and phi_e for anisotropic
        # materials): slices of eye_conditioned_weights, interpolated linearly between the eye
        # grid values by Mitsuba's MarginalContinuous2D{1,2} (sample() and eval() agree).
        res = int(sampling_resolution or (256 if self.isotropic else 128))
        self.thetas = np.linspace(0.0, math.pi / 2, N_THETA)
        phis = [0.0] if self.isotropic else np.linspace(0.0, 2 * math.pi, N_PHI + 1)
        weights, albedo = eye_conditioned_weights(material, res, self.thetas, phis)
        if self.isotropic:
            self.dist = mi.MarginalContinuous2D1(weights[0], [self.thetas.tolist()])
            a_theta = albedo[0]
        else:
            self.dist = mi.MarginalContinuous2D2(weights, [list(map(float, phis)), self.thetas.tolist()])
            a_theta = albedo[:-1].mean(0)
        # Probability of the specular technique, per eye theta (linear in theta between grid values).
        a_diff = float(material.rho_d @ np.asarray(L.LUMINANCE))
        if a_diff <= 0.0:
            ps = np.ones(N_THETA)  # no diffuse term: cosine sampling would be wasted
        else:
            ps = np.clip(a_theta / (a_theta + a_diff), 0.1, 0.9)
        self.p_spec_table = ps
        self.p_spec = float(ps[0])
        self._ps = mi.Float(ps.astype(np.float32)) if self.jit else ps

    # --- p(h) ----------------------------------------------------------------------------------
    def _fetch(self, idx, active):
        if self.jit:
            return self.dr.gather(self.mi.Color3f, self.flat, idx, active)
        t = self.flat[idx]
        return self.mi.Color3f(float(t[0]), float(t[1]), float(t[2]))

    def p(self, h, active=True):
        """p(h) (``mi.Color3f``): the exact lobe sum, or the bilinear table lookup of §3."""
        mi, dr = self.mi, self.dr
        if self.exact:
            r, g, b = L.p_of_h(h.x, h.y, h.z, self.centres, self.coefficients, self.material.lam,
                               self.isotropic, self.ops)
            return mi.Color3f(r, g, b)
        u, v = L.hemi_oct_encode(h.x, h.y, h.z, self.ops)
        n = self.res
        fx = dr.clip(u, 0.0, 1.0) * (n - 1)
        fy = dr.clip(v, 0.0, 1.0) * (n - 1)
        if self.jit:
            x0 = dr.clip(mi.Int32(dr.floor(fx)), 0, n - 2)
            y0 = dr.clip(mi.Int32(dr.floor(fy)), 0, n - 2)
            idx = mi.UInt32(y0 * n + x0)
        else:
            x0 = min(max(int(math.floor(fx)), 0), n - 2)
            y0 = min(max(int(math.floor(fy)), 0), n - 2)
            idx = y0 * n + x0
        tx = fx - x0
        ty = fy - y0
        c00 = self._fetch(idx, active)
        c01 = self._fetch(idx + 1, active)
        c10 = self._fetch(idx + n, active)
        c11 = self._fetch(idx + n + 1, active)
        return (1.0 - ty) * ((1.0 - tx) * c00 + tx * c01) + ty * ((1.0 - tx) * c10 + tx * c11)

    # --- f_r and pdf in the local frame ----------------------------------------------------------
    def _eye_params(self, e):
        """(theta_e in [0, pi/2], phi_e in [0, 2 pi)) of the eye direction."""
        dr = self.dr
        theta = dr.acos(dr.clip(e.z, 0.0, 1.0))
        phi = dr.atan2(e.y, e.x)
        phi = dr.select(phi < 0.0, phi + 2.0 * math.pi, phi)
        return theta, phi

    def _dist_params(self, theta, phi):
        return [theta] if self.isotropic else [phi, theta]

    def spec_probability(self, e, glossy=True, diffuse=True):
        """Probability that ``sample`` draws the specular technique, a function of the eye direction
        only (0 when the eye is below the shading horizon: the silhouette rule leaves the diffuse
        term only)."""
        mi, dr = self.mi, self.dr
        if not (self.specular and glossy):
            return 0.0 * e.z
        if not diffuse:
            return dr.select(e.z > 0.0, 1.0, 0.0)
        theta, _ = self._eye_params(e)
        t = theta * ((N_THETA - 1) / (math.pi / 2))
        if self.jit:
            i = dr.clip(mi.Int32(dr.floor(t)), 0, N_THETA - 2)
            a = dr.gather(mi.Float, self._ps, mi.UInt32(i))
            b = dr.gather(mi.Float, self._ps, mi.UInt32(i + 1))
        else:
            i = min(max(int(math.floor(t)), 0), N_THETA - 2)
            a, b = float(self._ps[i]), float(self._ps[i + 1])
        f = dr.clip(t - i, 0.0, 1.0)
        return dr.select(e.z > 0.0, a + (b - a) * f, 0.0)

    def eval(self, e, l, active=True, glossy=True, diffuse=True):
        """``f_r(l, e) * max(l.z, 0)`` (``mi.Color3f``)."""
        mi, dr = self.mi, self.dr
        k1, k2 = l.z, e.z
        lit = active & (k1 > 0.0)
        out = mi.Color3f(0.0)
        if diffuse:
            out = mi.Color3f(self.rho_d[0], self.rho_d[1], self.rho_d[2]) * (INV_PI * k1)
        if self.specular and glossy:
            both = lit & (k2 > 0.0)
            h = dr.normalize(e + l)
            s = L.specular_factor((l.x, l.y, l.z), (e.x, e.y, e.z), self.f0, self.ops)
            spec = self.p(h, both) * (s * k1)
            out = dr.select(both, out + spec, out)
        return dr.select(lit, out, 0.0)

    def pdf_specular(self, e, l, active=True):
        """Density (solid angle, light direction) of the specular technique."""
        mi, dr = self.mi, self.dr
        h = dr.normalize(e + l)
        eh = dr.dot(e, h)
        theta, phi = self._eye_params(e)
        hx, hy = h.x, h.y
        if self.isotropic:  # the slices are for an eye at azimuth 0: turn h by -phi_e
            c, s = dr.cos(phi), dr.sin(phi)
            hx, hy = c * h.x + s * h.y, c * h.y - s * h.x
        u, v = L.hemi_oct_encode(hx, hy, h.z, self.ops)
        ok = active & (eh > 0.0) & (h.z > 0.0) & (l.z > 0.0) & (e.z > 0.0)
        pdf_uv = self.dist.eval(mi.Point2f(u, v), self._dist_params(theta, phi), active=ok)
        jac = L.hemi_oct_jacobian(u, v, self.ops)
        return dr.select(ok, pdf_uv / (jac * 4.0 * eh), 0.0)

    def pdf(self, e, l, active=True, glossy=True, diffuse=True):
        """The exact density of :meth:`sample` (solid angle; 0 below the horizon)."""
        dr = self.dr
        ps = self.spec_probability(e, glossy, diffuse)
        pdf = 0.0 * l.z
        if diffuse:
            pdf = (1.0 - ps) * dr.maximum(l.z, 0.0) * INV_PI
        if self.specular and glossy:
            pdf = pdf + ps * self.pdf_specular(e, l, active)
        return dr.select(active & (l.z > 0.0), pdf, 0.0)

    def sample(self, e, sample1, sample2, active=True, glossy=True, diffuse=True):
        """Draws a light direction: returns (l, pdf, is_specular, valid)."""
        mi, dr = self.mi, self.dr
        ps = self.spec_probability(e, glossy, diffuse)
        if not diffuse and not (self.specular and glossy):
            return mi.Vector3f(0.0, 0.0, 1.0), 0.0 * e.z, active & False, active & False
        l = mi.warp.square_to_cosine_hemisphere(sample2)
        chose_spec = active & (sample1 < ps)
        if self.specular and glossy:
            theta, phi = self._eye_params(e)
            uv, _ = self.dist.sample(sample2, self._dist_params(theta, phi), active=chose_spec)
            hx, hy, hz = L.hemi_oct_decode(uv.x, uv.y, self.ops)
            if self.isotropic:  # back to the eye's azimuth
                c, s = dr.cos(phi), dr.sin(phi)
                hx, hy = c * hx - s * hy, s * hx + c * hy
            h = mi.Vector3f(hx, hy, hz)
            eh = dr.dot(e, h)
            l_spec = 2.0 * eh * h - e
            l = dr.select(chose_spec, l_spec, l)
            good = dr.select(chose_spec, eh > 0.0, True)
        else:
            good = True
        valid = active & good & (l.z > 0.0)
        pdf = self.pdf(e, l, valid, glossy, diffuse)
        valid = valid & (pdf > 0.0)
        return l, dr.select(valid, pdf, 0.0), chose_spec, valid


def make_bsdf_class():
    """The ``glint`` BSDF class for the current Mitsuba variant."""
    import drjit as dr
    import mitsuba as mi

    Glossy = mi.BSDFFlags.GlossyReflection
    Diffuse = mi.BSDFFlags.DiffuseReflection

    class GlintBSDF(mi.BSDF):
        """glint's BRDF (``filename``: ``<name>_ph.exr`` or ``<name>_lobes.json``).

        Optional: ``lambertian`` (bool; keep rho_d, drop the specular term), ``rho_d_override``
        (float or rgb; replaces rho_d and drops the specular term), ``sampling_resolution`` (int,
        the (u, v) resolution of the half-vector sampling slices; default 256 for isotropic
        materials, 128 for anisotropic ones).
        """

        force_lambertian = False

        def __init__(self, props, material: Material = None):
            super().__init__(props)
            if material is None:
                if "filename" not in props:
                    raise MaterialError("the glint BSDF needs a 'filename' (<name>_ph.exr or <name>_lobes.json)")
                name = str(props["filename"])
                path = name
                if not os.path.isabs(path):
                    fr = mi.file_resolver() if hasattr(mi, "file_resolver") else \
                        mi.Thread.thread().file_resolver()
                    path = str(fr.resolve(name))
                material = load_material(path)
            if "rho_d_override" in props:
                material = material.lambertian(np.asarray(props["rho_d_override"], dtype=float))
            elif ("lambertian" in props and bool(props["lambertian"])) or self.force_lambertian:
                material = material.lambertian()
            res = int(props["sampling_resolution"]) if "sampling_resolution" in props \
                else DEFAULT_SAMPLING_RESOLUTION
            self.core = GlintCore(material, res)
            self.anisotropic = (not material.isotropic) and self.core.specular
            glossy = Glossy | mi.BSDFFlags.FrontSide
            if self.anisotropic:
                glossy = glossy | mi.BSDFFlags.Anisotropic
            diffuse = Diffuse | mi.BSDFFlags.FrontSide
            self.m_components = [glossy, diffuse]
            self.m_flags = glossy | diffuse

        # --- frame (§2) --------------------------------------------------------------------------
        def local_frame(self, si, active=True):
            """(x, y, n) of glint's frame in world space: n = Mitsuba's shading normal, x the
            interpolated ``vertex_tangent`` made orthogonal to n, y = (n x x) sign(handedness).
            Without a tangent attribute (or for isotropic materials) Mitsuba's frame is used."""
            n = si.sh_frame.n
            if not self.anisotropic:
                return si.sh_frame.s, si.sh_frame.t, n
            if dr.is_jit_v(mi.Float):
                shape = si.shape
                has_t = shape.has_attribute("vertex_tangent", active)
                t = mi.Vector3f(shape.eval_attribute_3("vertex_tangent", si, active & has_t))
                t = dr.select(has_t, t, 0.0)
                has_w = shape.has_attribute("vertex_handedness", active)
                w = shape.eval_attribute_1("vertex_handedness", si, active & has_w)
                w = dr.select(has_w, w, 1.0)
            else:
                shape = si.shape
                t = mi.Vector3f(0.0)
                w = 1.0
                if shape is not None and shape.has_attribute("vertex_tangent"):
                    t = mi.Vector3f(shape.eval_attribute_3("vertex_tangent", si, active))
                if shape is not None and shape.has_attribute("vertex_handedness"):
                    w = shape.eval_attribute_1("vertex_handedness", si, active)
            tp = t - n * dr.dot(n, t)
            l2 = dr.squared_norm(tp)
            ok = l2 > 1e-12 * dr.maximum(dr.squared_norm(t), 1e-30)
            x = dr.select(ok, tp * dr.rsqrt(dr.select(ok, l2, 1.0)), si.sh_frame.s)
            y = dr.cross(n, x) * dr.select(w >= 0.0, 1.0, -1.0)
            return x, y, n

        def _to_glint(self, si, wo, active):
            """(eye, light, frame) in glint's frame from si.wi and wo (Mitsuba's local frame)."""
            if not self.anisotropic:
                return si.wi, wo, None
            x, y, n = self.local_frame(si, active)
            a = si.sh_frame.to_world(si.wi)
            e = mi.Vector3f(dr.dot(a, x), dr.dot(a, y), dr.dot(a, n))
            if wo is None:
                return e, None, (x, y, n)
            b = si.sh_frame.to_world(wo)
            return e, mi.Vector3f(dr.dot(b, x), dr.dot(b, y), dr.dot(b, n)), (x, y, n)

        @staticmethod
        def _enabled(ctx):
            return ctx.is_enabled(Glossy, 0), ctx.is_enabled(Diffuse, 1)

        # --- mi.BSDF interface -------------------------------------------------------------------
        def eval(self, ctx, si, wo, active=True):
            g, d = self._enabled(ctx)
            e, l, _ = self._to_glint(si, wo, active)
            return self.core.eval(e, l, active, g, d)

        def pdf(self, ctx, si, wo, active=True):
            g, d = self._enabled(ctx)
            e, l, _ = self._to_glint(si, wo, active)
            return self.core.pdf(e, l, active, g, d)

        def eval_pdf(self, ctx, si, wo, active=True):
            g, d = self._enabled(ctx)
            e, l, _ = self._to_glint(si, wo, active)
            return self.core.eval(e, l, active, g, d), self.core.pdf(e, l, active, g, d)

        def sample(self, ctx, si, sample1, sample2, active=True):
            g, d = self._enabled(ctx)
            e, _, frame = self._to_glint(si, None, active)
            l, pdf, chose_spec, valid = self.core.sample(e, sample1, sample2, active, g, d)
            f = self.core.eval(e, l, valid, g, d)
            if frame is None:
                wo = l
            else:
                x, y, n = frame
                wo = si.sh_frame.to_local(x * l.x + y * l.y + n * l.z)
            bs = dr.zeros(mi.BSDFSample3f)
            bs.wo = wo
            bs.pdf = pdf
            bs.eta = 1.0
            bs.sampled_type = dr.select(chose_spec, mi.UInt32(int(Glossy)), mi.UInt32(int(Diffuse)))
            bs.sampled_component = dr.select(chose_spec, mi.UInt32(0), mi.UInt32(1))
            weight = dr.select(valid, f / dr.select(valid, pdf, 1.0), 0.0)
            return bs, weight

        def eval_diffuse_reflectance(self, si, active=True):
            r = self.core.rho_d
            return mi.Color3f(r[0], r[1], r[2])

        def traverse(self, callback):
            pass

        def parameters_changed(self, keys=[]):
            pass

        def to_string(self):
            m = self.core.material
            kind = "lobes" if m.exact else f"table {m.table.shape[0]}x{m.table.shape[0]}"
            return (f"GlintBSDF[source={m.source!r}, {kind}, lambda={m.lam:g}, "
                    f"isotropic={m.isotropic}, f0={m.f0:g}, rho_d={list(m.rho_d)}, "
                    f"specular={self.core.specular}, p_spec={self.core.p_spec:.3f}]")

    return GlintBSDF
