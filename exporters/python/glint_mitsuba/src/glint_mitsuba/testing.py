"""Small inputs in the formats ``glint export --formats mitsuba`` writes (for tests and experiments):
PLY meshes with normals and tangents, synthetic materials, the table EXR with its glint.* header,
the lobes JSON, environment maps, and the scene XML."""

from __future__ import annotations

import json
import math
import os

import numpy as np

from .lobes import LUMINANCE
from .material import Material, material_to_dict, specular_albedo_normal, tabulate

# ------------------------------------------------------------------------------------------------
# Meshes


def write_ply(path, positions, normals, faces, uvs=None, tangents=None, handedness=None):
    """Binary little-endian PLY: float x y z nx ny nz [u v] [tangent_x tangent_y tangent_z
    handedness_0]; faces ``property list uchar int vertex_indices``."""
    v = np.asarray(positions, float)
    cols = [v, np.asarray(normals, float)]
    props = ["x", "y", "z", "nx", "ny", "nz"]
    if uvs is not None:
        cols.append(np.asarray(uvs, float))
        props += ["u", "v"]
    if tangents is not None:
        w = np.ones(len(v)) if handedness is None else np.asarray(handedness, float)
        cols += [np.asarray(tangents, float), w[:, None]]
        props += ["tangent_x", "tangent_y", "tangent_z", "handedness_0"]
    data = np.ascontiguousarray(np.concatenate(cols, axis=1).astype("<f4"))
    f = np.asarray(faces, dtype="<i4")
    header = ("ply\nformat binary_little_endian 1.0\n"
              f"element vertex {len(v)}\n" + "".join(f"property float {p}\n" for p in props)
              + f"element face {len(f)}\nproperty list uchar int vertex_indices\nend_header\n")
    faces_bytes = np.zeros(len(f), dtype=[("n", "u1"), ("i", "<i4", (3,))])
    faces_bytes["n"] = 3
    faces_bytes["i"] = f
    with open(path, "wb") as fh:
        fh.write(header.encode("ascii"))
        fh.write(data.tobytes())
        fh.write(faces_bytes.tobytes())


def uv_sphere(n_theta=24, n_phi=48, radius=1.0, centre=(0.0, 0.0, 0.0)):
    """A UV sphere (+Y pole): positions, normals, faces, uvs, tangents (d/dphi), handedness (+1)."""
    verts, norms, uvs, tans = [], [], [], []
    for i in range(n_theta + 1):
        th = math.pi * i / n_theta
        for j in range(n_phi + 1):
            ph = 2 * math.pi * j / n_phi
            n = (math.sin(th) * math.sin(ph), math.cos(th), math.sin(th) * math.cos(ph))
            verts.append([centre[k] + radius * n[k] for k in range(3)])
            norms.append(n)
            uvs.append((j / n_phi, 1 - i / n_theta))
            tans.append((math.cos(ph), 0.0, -math.sin(ph)))
    faces = []
    row = n_phi + 1
    for i in range(n_theta):
        for j in range(n_phi):
            a, b = i * row + j, i * row + j + 1
            c, d = a + row, b + row
            if i > 0:
                faces.append((a, c, b))
            if i < n_theta - 1:
                faces.append((b, c, d))
    return (np.array(verts), np.array(norms), np.array(faces), np.array(uvs), np.array(tans),
            np.ones(len(verts)))


def quad(size=1.0, normal_tilt=0.0):
    """A square in the z = 0 plane facing +z (two triangles); tangent +x, handedness +1."""
    s = size / 2
    v = np.array([[-s, -s, 0], [s, -s, 0], [s, s, 0], [-s, s, 0]], float)
    n = np.tile([0.0, 0.0, 1.0], (4, 1))
    if normal_tilt:
        n[:, 0] = normal_tilt
        n /= np.linalg.norm(n, axis=1)[:, None]
    f = np.array([[0, 1, 2], [0, 2, 3]])
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    t = np.tile([1.0, 0.0, 0.0], (4, 1))
    return v, n, f, uv, t, np.ones(4)


# ------------------------------------------------------------------------------------------------
# Materials


def example_material(isotropic=False, lam=81.0, f0=0.04, rho_d=(0.31, 0.22, 0.13), n=12, seed=1,
                     albedo=0.5) -> Material:
    """A synthetic material with positive coefficients, scaled so that the specular albedo (luminance,
    eye on the normal) is ``albedo``.

    Anisotropic: 15 point lobes at normalize(R(0.5 rad) (a, b), 1), a in 5 steps over [-0.3, 0.3],
    b in 3 steps over [-0.12, 0.12], weighted exp(-(a/0.2)^2 - (b/0.08)^2): a highlight elongated
    0.5 rad from the tangent, so a 90 degree turn of the tangent and a mirrored y both show. Isotropic: ``n`` ring lobes at
    theta_j = (pi/2) j / n (stored at azimuth 0), weighted exp(-3 theta_j)."""
    rng = np.random.default_rng(seed)
    if isotropic:
        th = (math.pi / 2) * np.arange(n) / n
        centres = np.stack([np.sin(th), np.zeros(n), np.cos(th)], 1)
        base = np.exp(-3 * th)
    else:
        a, b = np.meshgrid(np.linspace(-0.3, 0.3, 5), np.linspace(-0.12, 0.12, 3))
        a, b = a.ravel(), b.ravel()
        c, s = math.cos(0.5), math.sin(0.5)
        centres = np.stack([c * a - s * b, s * a + c * b, np.ones_like(a)], 1)
        centres /= np.linalg.norm(centres, axis=1)[:, None]
        base = np.exp(-(a / 0.2) ** 2 - (b / 0.08) ** 2)
    k = len(centres)
    coeffs = np.stack([base * (0.8 + 0.4 * rng.random(k)) for _ in range(3)])
    m = Material(lam=lam, isotropic=isotropic, f0=f0, rho_d=np.asarray(rho_d, float),
                 centres=centres, coefficients=coeffs, source="example")
    a_spec = float(specular_albedo_normal(tabulate(m, 257), f0) @ np.asarray(LUMINANCE))
    m.coefficients = coeffs * (albedo / a_spec)
    return m


def write_lobes_json(path, material: Material):
    with open(path, "w", encoding="utf-8") as fh:
        json.dump(material_to_dict(material), fh)


def write_ph_exr(path, material: Material, resolution=512, table=None):
    """``<name>_ph.exr`` as glint writes it: RGB float table + glint.* header attributes."""
    import OpenEXR

    if table is None:
        table = tabulate(material, resolution)
    table = np.asarray(table, dtype=np.float32)
    header = {
        "compression": OpenEXR.NO_COMPRESSION,
        "type": OpenEXR.scanlineimage,
        "glint.model": "dbrdf-srbf",
        "glint.name": os.path.basename(path).replace("_ph.exr", ""),
        "glint.layout": (f"isotropic-{len(material.centres)}" if material.isotropic
                         else f"hemicube-{len(material.centres)}") if material.exact else "unknown",
        "glint.parameterisation": "hemi-octahedral: see docs/conventions.md section 3",
        "glint.version": 1,
        "glint.isotropic": int(material.isotropic),
        "glint.lobe_count": int(len(material.centres)) if material.exact else 0,
        "glint.lambda": float(material.lam),
        "glint.f0": float(material.f0),
        "glint.rho_d": np.asarray(material.rho_d, dtype=np.float64),
        "glint.rho_d_r": float(material.rho_d[0]),
        "glint.rho_d_g": float(material.rho_d[1]),
        "glint.rho_d_b": float(material.rho_d[2]),
    }
    channels = {c: np.ascontiguousarray(table[:, :, k]) for k, c in enumerate("RGB")}
    OpenEXR.File(header, channels).write(path)
    return table


def write_env_exr(path, image):
    """An RGB float EXR (H x W x 3), e.g. an environment map in Mitsuba's orientation."""
    import OpenEXR

    image = np.asarray(image, dtype=np.float32)
    channels = {c: np.ascontiguousarray(image[:, :, k]) for k, c in enumerate("RGB")}
    OpenEXR.File({"compression": OpenEXR.NO_COMPRESSION, "type": OpenEXR.scanlineimage},
                 channels).write(path)


# ------------------------------------------------------------------------------------------------
# Scenes


def scene_xml(name, eye, target, up=(0, 1, 0), width=32, height=24, fov=40.0, spp=16,
              ray_offset=1e-4, near=1e-2, far=100.0, env_rotation=0.0, material_file=None,
              bsdf_extra=""):
    """The scene XML in the layout ``glint export --formats mitsuba`` writes."""
    mat = material_file or f"{name}_ph.exr"
    f = lambda v: ", ".join(f"{x:.9g}" for x in v)  # noqa: E731
    return f"""<scene version="3.0.0">
    <default name="spp" value="{spp}"/>
    <integrator type="glint_direct">
        <float name="ray_offset" value="{ray_offset:.9g}"/>
        <boolean name="pixel_centres" value="true"/>
    </integrator>
    <sensor type="perspective">
        <string name="fov_axis" value="y"/>
        <float name="fov" value="{fov:.9g}"/>
        <float name="near_clip" value="{near:.9g}"/>
        <float name="far_clip" value="{far:.9g}"/>
        <transform name="to_world"><lookat origin="{f(eye)}" target="{f(target)}" up="{f(up)}"/></transform>
        <sampler type="independent"><integer name="sample_count" value="$spp"/></sampler>
        <film type="hdrfilm"><integer name="width" value="{width}"/><integer name="height" value="{height}"/>
              <string name="pixel_format" value="rgba"/><rfilter type="box"/></film>
    </sensor>
    <emitter type="envmap">
        <string name="filename" value="{name}_env.exr"/>
        <transform name="to_world"><rotate y="1" angle="{env_rotation:.9g}"/></transform>
    </emitter>
    <shape type="ply">
        <string name="filename" value="{name}_mesh.ply"/>
        <bsdf type="glint"><string name="filename" value="{mat}"/>{bsdf_extra}</bsdf>
    </shape>
</scene>
"""


def write_sphere_scene(folder, name="ball", material=None, env=None, width=32, height=24, spp=16,
                       table_resolution=128, use_json=False, n_theta=24, n_phi=48):
    """A unit sphere at the origin seen from +z at distance 4, under ``env`` (H x W x 3; default a
    constant 1). Writes the mesh, env, table EXR, lobes JSON and XML; returns the XML path."""
    os.makedirs(folder, exist_ok=True)
    material = material or example_material(isotropic=True)
    v, n, f, uv, t, w = uv_sphere(n_theta, n_phi)
    write_ply(os.path.join(folder, f"{name}_mesh.ply"), v, n, f, uv, t, w)
    write_env_exr(os.path.join(folder, f"{name}_env.exr"),
                  np.ones((16, 32, 3)) if env is None else env)
    write_ph_exr(os.path.join(folder, f"{name}_ph.exr"), material, table_resolution)
    write_lobes_json(os.path.join(folder, f"{name}_lobes.json"), material)
    xml = scene_xml(name, eye=(0, 0, 4), target=(0, 0, 0), width=width, height=height, spp=spp,
                    ray_offset=1e-4 * 2 * math.sqrt(3), near=1.0, far=10.0,
                    material_file=f"{name}_lobes.json" if use_json else None)
    path = os.path.join(folder, f"{name}_mitsuba.xml")
    with open(path, "w", encoding="utf-8") as fh:
        fh.write(xml)
    return path


# ------------------------------------------------------------------------------------------------
# Evaluating a BSDF on numpy arrays (any variant: vectorised in JIT variants, a loop in scalar ones)


def hemisphere_quadrature(n):
    """Midpoint rule on the hemi-octahedral square: directions (n*n, 3) and solid-angle weights."""
    from . import lobes as L

    t = (np.arange(n) + 0.5) / n
    u, v = np.meshgrid(t, t)
    x, y, z = L.hemi_oct_decode(u, v)
    w = L.hemi_oct_jacobian(u, v) / (n * n)
    return np.stack([x, y, z], -1).reshape(-1, 3), w.reshape(-1)


def _vec(mi, a):
    a = np.asarray(a, dtype=np.float32)
    return mi.Vector3f(mi.Float(a[..., 0]), mi.Float(a[..., 1]), mi.Float(a[..., 2]))


def _si(mi, dr, e, frame=None):
    si = dr.zeros(mi.SurfaceInteraction3f)
    if frame is None:
        si.sh_frame = mi.Frame3f(mi.Vector3f(1, 0, 0), mi.Vector3f(0, 1, 0), mi.Vector3f(0, 0, 1))
    else:
        si.sh_frame = mi.Frame3f(*(mi.Vector3f(*map(float, f)) for f in frame))
    si.wi = e
    return si


def bsdf_eval_pdf(bsdf, e, l):
    """``bsdf.eval`` (N x 3) and ``bsdf.pdf`` (N) for eye directions ``e`` and light directions ``l``
    (N x 3, Mitsuba's local frame = the canonical frame)."""
    import drjit as dr
    import mitsuba as mi

    ctx = mi.BSDFContext()
    e = np.asarray(e, float).reshape(-1, 3)
    l = np.asarray(l, float).reshape(-1, 3)
    e, l = np.broadcast_arrays(e, l)
    if dr.is_jit_v(mi.Float):
        si = _si(mi, dr, _vec(mi, e))
        f, p = bsdf.eval_pdf(ctx, si, _vec(mi, l))
        return np.array(f).reshape(3, -1).T.astype(float), np.array(p, dtype=float).reshape(-1)
    fs, ps = [], []
    for a, b in zip(e, l):
        si = _si(mi, dr, mi.Vector3f(*map(float, a)))
        f, p = bsdf.eval_pdf(ctx, si, mi.Vector3f(*map(float, b)))
        fs.append(list(f))
        ps.append(float(p))
    return np.array(fs, float), np.array(ps, float)


def bsdf_sample(bsdf, e, u1, u2):
    """``bsdf.sample`` for one eye direction and N random numbers: (wo N x 3, pdf N, weight N x 3)."""
    import drjit as dr
    import mitsuba as mi

    ctx = mi.BSDFContext()
    e = np.asarray(e, float)
    u1 = np.asarray(u1, float)
    u2 = np.asarray(u2, float).reshape(-1, 2)
    if dr.is_jit_v(mi.Float):
        n = len(u1)
        si = _si(mi, dr, _vec(mi, np.tile(e, (n, 1))))
        bs, w = bsdf.sample(ctx, si, mi.Float(u1.astype(np.float32)),
                            mi.Point2f(mi.Float(u2[:, 0].astype(np.float32)),
                                       mi.Float(u2[:, 1].astype(np.float32))))
        return (np.array(bs.wo).reshape(3, -1).T.astype(float), np.array(bs.pdf, dtype=float).reshape(-1),
                np.array(w).reshape(3, -1).T.astype(float))
    wos, pdfs, ws = [], [], []
    si = _si(mi, dr, mi.Vector3f(*map(float, e)))
    for a, (b, c) in zip(u1, u2):
        bs, w = bsdf.sample(ctx, si, float(a), mi.Point2f(float(b), float(c)))
        wos.append(list(bs.wo))
        pdfs.append(float(bs.pdf))
        ws.append(list(w))
    return np.array(wos, float), np.array(pdfs, float), np.array(ws, float)
