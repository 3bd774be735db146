"""Mitsuba 3 plugins for glint materials (docs/conventions.md is the specification).

    import mitsuba as mi
    mi.set_variant("llvm_ad_rgb")        # or "scalar_rgb"
    import glint_mitsuba
    glint_mitsuba.register()             # BSDF "glint", integrator "glint_direct"
    scene = mi.load_file("NAME_mitsuba.xml")

``register(lambertian=True)`` makes every ``glint`` BSDF its Lambertian copy (rho_d only).
"""

from __future__ import annotations

from .material import Material, MaterialError, load_material, tabulate  # noqa: F401

__all__ = ["register", "default_variant", "Material", "MaterialError", "load_material", "tabulate",
           "bsdf_class", "integrator_class"]
__version__ = "0.1.0"

_CLASSES = {}


def _classes():
    import mitsuba as mi

    variant = mi.variant()
    if variant is None:
        raise RuntimeError("set a Mitsuba variant (mi.set_variant) before glint_mitsuba.register()")
    if variant not in _CLASSES:
        from .bsdf import make_bsdf_class
        from .integrator import make_integrator_class

        bsdf = make_bsdf_class()

        class LambertianGlintBSDF(bsdf):
            force_lambertian = True

        _CLASSES[variant] = (bsdf, LambertianGlintBSDF, make_integrator_class())
    return _CLASSES[variant]


def bsdf_class(lambertian: bool = False):
    """The ``glint`` BSDF class of the current variant."""
    b, lb, _ = _classes()
    return lb if lambertian else b


def integrator_class():
    """The ``glint_direct`` integrator class of the current variant."""
    return _classes()[2]


def register(lambertian: bool = False) -> None:
    """Registers the ``glint`` BSDF and the ``glint_direct`` integrator for the current variant."""
    import mitsuba as mi

    bsdf = bsdf_class(lambertian)
    integ = integrator_class()
    mi.register_bsdf("glint", lambda props: bsdf(props))
    mi.register_integrator("glint_direct", lambda props: integ(props))


def default_variant() -> str:
    """``llvm_ad_rgb`` when DRJIT_LIBLLVM_PATH is set and the LLVM back end loads, else ``scalar_rgb``.

    (Without DRJIT_LIBLLVM_PATH, Dr.Jit would pick the system's libLLVM, which on Debian 12 is LLVM 15
    and aborts the process; so the JIT variant is only tried when the variable names a library.)
    """
    import os

    import mitsuba as mi

    lib = os.environ.get("DRJIT_LIBLLVM_PATH", "")
    if lib and os.path.isfile(lib) and "llvm_ad_rgb" in mi.variants():
        try:
            mi.set_variant("llvm_ad_rgb")
            import drjit as dr

            dr.eval(dr.llvm.Float(1.0) + 1.0)
            return "llvm_ad_rgb"
        except Exception:
            pass
    return "scalar_rgb"
