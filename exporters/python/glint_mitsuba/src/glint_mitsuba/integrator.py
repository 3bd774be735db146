"""The ``glint_direct`` integrator: glint's Monte Carlo reference in Mitsuba 3 (docs/conventions.md
§1, §4, §6).

- Direct light from the scene's environment emitter only (other emitters are ignored), shadowed by
  the scene's shapes, no interreflection; MIS (power heuristic) between environment sampling and
  BSDF sampling.
- Shadow rays leave from the smooth-surface point of §6 (Hanika 2021) offset by ``ray_offset``
  (world units; default 1e-4 x the diagonal of the scene's bounding box) along the shading normal,
  with no maximum distance.
- Camera rays that miss return the environment (so the background is the map seen through the
  pixel); the film's alpha channel (``pixel_format`` ``rgba``) is the coverage.
- ``pixel_centres`` (default true): every sample of pixel (x, y) is the ray through its centre
  (``render`` generates the rays itself instead of jittering them), so with a ``box`` filter each
  pixel holds the average of its centre ray's estimates and the alpha is exactly 0 or 1.
- ``stratified`` (bool, default true; ``render`` only): the 2D samples of the environment and of the
  BSDF form a Hammersley set over each pixel's samples, rotated per pixel (Cranley–Patterson), as in
  glint's reference; false: every random number comes from the scene's sampler.
- ``max_wavefront`` (int, default 2^22): samples traced at once in the JIT variants (more samples
  per pixel are rendered in passes into the same film block).
"""

from __future__ import annotations



def make_integrator_class():
    """The ``glint_direct`` integrator class for the current Mitsuba variant."""
    import drjit as dr
    import mitsuba as mi

    class GlintDirect(mi.SamplingIntegrator):
        def __init__(self, props):
            super().__init__(props)
            self.ray_offset = float(props["ray_offset"]) if "ray_offset" in props else -1.0
            self.pixel_centres = bool(props["pixel_centres"]) if "pixel_centres" in props else True
            self.max_wavefront = int(props["max_wavefront"]) if "max_wavefront" in props else 1 << 22
            self.stratified = bool(props["stratified"]) if "stratified" in props else True
            self._meshes = None

        # --- helpers -----------------------------------------------------------------------------
        def offset_for(self, scene):
            if self.ray_offset >= 0:
                return self.ray_offset
            b = scene.bbox()
            return 1e-4 * float(dr.norm(b.max - b.min)) if b.valid() else 1e-4

        def smooth_point(self, scene, si, active=True):
            """q = p - sum_i b_i min(0, (p - p_i).n_i) n_i on the hit triangle (§6)."""
            p = si.p
            if self._meshes is None or self._meshes[0] is not scene:
                # (holding the Python objects also makes scalar variants hand back si.shape as
                # these same mi.Mesh instances)
                self._meshes = (scene, [s for s in scene.shapes()
                                        if isinstance(s, mi.Mesh) and s.has_vertex_normals()])
            meshes = self._meshes[1]
            if dr.is_jit_v(mi.Float):
                q = mi.Point3f(p)
                for m in meshes:
                    sel = active & (si.shape == mi.ShapePtr(m))
                    q = dr.select(sel, _smooth(m, si.prim_index, p, sel), q)
                return q
            shape = si.shape
            for m in meshes:
                if shape is m:
                    return _smooth(m, si.prim_index, p, active)
            return mi.Point3f(p)

        def shade(self, scene, sampler, ray, active=True, u_env=None, u_bsdf=None):
            """(radiance, hit): direct environment light at the first hit, or the environment.
            ``u_env``, ``u_bsdf``: the 2D samples of the two strategies (default: from ``sampler``)."""
            si = scene.ray_intersect(ray, active)
            hit = active & si.is_valid()
            miss = active & dr.select(hit, False, True)
            env = scene.environment()
            result = mi.Color3f(0.0)
            if env is None:
                return result, hit
            si_env = dr.zeros(mi.SurfaceInteraction3f)
            si_env.wi = -ray.d
            si_env.wavelengths = ray.wavelengths
            result = dr.select(miss, env.eval(si_env, miss), result)
            if not dr.is_jit_v(mi.Float) and not hit:
                return result, hit  # scalar: no shape to ask for a BSDF

            bsdf = si.bsdf(ray)
            ctx = mi.BSDFContext()
            eps = self.offset_for(scene)
            n = si.sh_frame.n
            origin = self.smooth_point(scene, si, hit) + n * eps

            # Environment sampling.
            if u_env is None:
                u_env = sampler.next_2d(hit)
            ds, em_weight = env.sample_direction(si, u_env, hit)
            ok = hit & (ds.pdf > 0.0)
            wo = si.to_local(ds.d)
            f, pdf_b = bsdf.eval_pdf(ctx, si, wo, ok)
            ok = ok & (dr.max(f) > 0.0)
            blocked = scene.ray_test(mi.Ray3f(origin, ds.d), ok)
            ok = ok & dr.select(blocked, False, True)
            w = _power(ds.pdf, pdf_b)
            result = dr.select(ok, result + em_weight * f * w, result)

            # BSDF sampling.
            u1 = sampler.next_1d(hit)
            if u_bsdf is None:
                u_bsdf = sampler.next_2d(hit)
            bs, bw = bsdf.sample(ctx, si, u1, u_bsdf, hit)
            ok = hit & (bs.pdf > 0.0) & (dr.max(bw) > 0.0)
            d = si.to_world(bs.wo)
            blocked = scene.ray_test(mi.Ray3f(origin, d), ok)
            ok = ok & dr.select(blocked, False, True)
            si_b = dr.zeros(mi.SurfaceInteraction3f)
            si_b.wi = -d
            si_b.wavelengths = si.wavelengths
            le = env.eval(si_b, ok)
            ds_b = dr.zeros(mi.DirectionSample3f) if dr.is_jit_v(mi.Float) else mi.DirectionSample3f()
            ds_b.d = d
            pdf_e = env.pdf_direction(si, ds_b, ok)
            w = _power(bs.pdf, pdf_e)
            result = dr.select(ok, result + bw * le * w, result)
            return result, hit

        # --- mi.SamplingIntegrator interface -----------------------------------------------------
        def sample(self, scene, sampler, ray, medium=None, active=True):
            """Per-ray estimate (used if Mitsuba's own render loop drives this integrator; it then
            jitters inside pixels, whatever ``pixel_centres`` says)."""
            result, hit = self.shade(scene, sampler, mi.Ray3f(ray), active)
            return result, hit, []

        def aov_names(self):
            return []

        def render(self, scene, sensor=0, seed=0, spp=0, develop=True, evaluate=True):
            if isinstance(sensor, int):
                sensor = scene.sensors()[sensor]
            film = sensor.film()
            sampler = sensor.sampler().clone()
            if spp:
                sampler.set_sample_count(spp)
            spp = sampler.sample_count()
            film.prepare([])
            block = film.create_block()
            has_alpha = mi.has_flag(film.flags(), mi.FilmFlags.Alpha)
            seed = int(seed[0] if hasattr(seed, "__len__") else seed)
            if dr.is_jit_v(mi.Float):
                self._render_jit(scene, sensor, film, sampler, block, spp, seed, has_alpha)
            else:
                self._render_scalar(scene, sensor, film, sampler, block, spp, seed, has_alpha)
            film.put_block(block)
            if not develop:
                return mi.TensorXf()
            return film.develop()

        def _camera_rays(self, sensor, film, sampler, px, py):
            size = film.crop_size()
            offset = film.crop_offset()
            pos = mi.Point2f(mi.Float(px), mi.Float(py))
            if self.pixel_centres:
                pos = pos + 0.5
            else:
                pos = pos + sampler.next_2d()
            pos_rel = mi.Point2f(pos.x / size[0], pos.y / size[1])
            time = sensor.shutter_open()
            if sensor.shutter_open_time() > 0:
                time = time + sampler.next_1d() * sensor.shutter_open_time()
            wav = sampler.next_1d() if mi.is_spectral else 0.5
            aperture = sampler.next_2d() if sensor.needs_aperture_sample() else mi.Point2f(0.5)
            ray, weight = sensor.sample_ray(time, wav, pos_rel, aperture)
            return ray, weight, mi.Point2f(pos.x + offset[0], pos.y + offset[1])

        def _splat(self, block, pos, value, hit, has_alpha):
            alpha = dr.select(hit, 1.0, 0.0)
            if has_alpha:
                block.put(pos, [value.x, value.y, value.z, alpha, 1.0])
            else:
                block.put(pos, [value.x, value.y, value.z, 1.0])

        def _render_jit(self, scene, sensor, film, sampler, block, spp, seed, has_alpha):
            w, h = int(film.crop_size()[0]), int(film.crop_size()[1])
            n_pix = w * h
            cap = max(1, min(spp, self.max_wavefront // max(n_pix, 1)))
            n = max(d for d in range(1, cap + 1) if spp % d == 0)  # samples per pixel per pass
            sampler.set_samples_per_wavefront(n)
            done, k = 0, 0
            while done < spp:
                wavefront = n_pix * n
                sampler.seed((seed * 65537 + k) & 0xFFFFFFFF, wavefront)
                idx = dr.arange(mi.UInt32, wavefront)
                pix = idx // n if n > 1 else idx
                py = pix // w
                px = pix - py * w
                ray, weight, pos = self._camera_rays(sensor, film, sampler, px, py)
                u_env = u_bsdf = None
                if self.stratified:
                    s_idx = (idx - pix * n if n > 1 else mi.UInt32(0)) + done
                    u_env, u_bsdf = _strata(s_idx, spp, pix, seed)
                value, hit = self.shade(scene, sampler, ray, True, u_env, u_bsdf)
                self._splat(block, pos, value * weight, hit, has_alpha)
                dr.eval(block.tensor())
                done += n
                k += 1

        def _render_scalar(self, scene, sensor, film, sampler, block, spp, seed, has_alpha):
            w, h = int(film.crop_size()[0]), int(film.crop_size()[1])
            sampler.seed(seed)
            for py in range(h):
                for px in range(w):
                    for s_idx in range(spp):
                        ray, weight, pos = self._camera_rays(sensor, film, sampler, px, py)
                        u_env = u_bsdf = None
                        if self.stratified:
                            u_env, u_bsdf = _strata(s_idx, spp, py * w + px, seed)
                        value, hit = self.shade(scene, sampler, ray, True, u_env, u_bsdf)
                        self._splat(block, pos, value * weight, hit, has_alpha)
                        sampler.advance()

        def to_string(self):
            return (f"GlintDirect[ray_offset={self.ray_offset:g} (negative: 1e-4 x bbox diagonal), "
                    f"pixel_centres={self.pixel_centres}, stratified={self.stratified}]")

    def _radical_inverse(i):
        if dr.is_jit_v(mi.Float):
            return mi.Float(dr.brev(mi.UInt32(i))) * (1.0 / 4294967296.0)
        return int(format(int(i) & 0xFFFFFFFF, "032b")[::-1], 2) * (1.0 / 4294967296.0)

    def _frac(x):
        return x - dr.floor(x)

    def _strata(s_idx, spp, pix, seed):
        """Sample s_idx of a pixel's spp: two points of a Hammersley set (i/spp, radical inverse i),
        each rotated by a per-pixel random offset (Cranley–Patterson)."""
        key = (int(seed) * 4) & 0xFFFFFFFF
        pix = mi.UInt32(pix)
        r = [mi.sample_tea_float32(pix, mi.UInt32((key + j) & 0xFFFFFFFF)) for j in range(4)]
        a = (mi.Float(s_idx) + 0.5) * (1.0 / spp)
        b = _radical_inverse(s_idx)
        return (mi.Point2f(_frac(a + r[0]), _frac(b + r[1])),
                mi.Point2f(_frac(a + r[2]), _frac(b + r[3])))

    def _power(a, b):
        a2 = a * a
        b2 = b * b
        return dr.select(a2 + b2 > 0.0, a2 / (a2 + b2), 0.0)

    def _smooth(mesh, prim, p, active):
        fi = mesh.face_indices(prim, active)
        ps = [mesh.vertex_position(fi[k], active) for k in range(3)]
        ns = [dr.normalize(mesh.vertex_normal(fi[k], active)) for k in range(3)]
        e1 = ps[1] - ps[0]
        e2 = ps[2] - ps[0]
        v = p - ps[0]
        d00, d01, d11 = dr.dot(e1, e1), dr.dot(e1, e2), dr.dot(e2, e2)
        d20, d21 = dr.dot(v, e1), dr.dot(v, e2)
        den = d00 * d11 - d01 * d01
        inv = 1.0 / dr.select(den != 0.0, den, 1.0)
        b1 = (d11 * d20 - d01 * d21) * inv
        b2 = (d00 * d21 - d01 * d20) * inv
        bs = [1.0 - b1 - b2, b1, b2]
        q = mi.Point3f(p)
        for k in range(3):
            q = q - ns[k] * (bs[k] * dr.minimum(dr.dot(p - ps[k], ns[k]), 0.0))
        return q

    return GlintDirect
