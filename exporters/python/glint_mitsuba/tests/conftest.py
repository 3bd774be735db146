"""Test setup for glint_mitsuba.

- The package is imported from ../src when it is not installed.
- Tests that need Mitsuba skip when it is not importable.
- The llvm_ad_rgb tests run only when DRJIT_LIBLLVM_PATH names a libLLVM >= 16 (CI sets it, e.g.
  /usr/lib/x86_64-linux-gnu/libLLVM-19.so); without it they skip, because Dr.Jit would otherwise
  load the system's default libLLVM, which on Debian 12 is LLVM 15 and aborts the process.
"""

import os
import sys

import pytest

SRC = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "src")
if SRC not in sys.path:
    sys.path.insert(0, SRC)

LLVM_OK = bool(os.environ.get("DRJIT_LIBLLVM_PATH")) and os.path.isfile(os.environ["DRJIT_LIBLLVM_PATH"])


def _use(name):
    mi = pytest.importorskip("mitsuba")
    if name.startswith("llvm") and not LLVM_OK:
        pytest.skip("DRJIT_LIBLLVM_PATH is unset: llvm variants skipped (CI sets it to libLLVM >= 16)")
    mi.set_variant(name)
    import glint_mitsuba

    glint_mitsuba.register()
    return name


@pytest.fixture(params=["scalar_rgb", "llvm_ad_rgb"])
def variant(request):
    """Each Mitsuba variant in turn (llvm skipped without DRJIT_LIBLLVM_PATH)."""
    return _use(request.param)


@pytest.fixture
def fast_variant():
    """llvm_ad_rgb where available (vectorised statistics), else scalar_rgb with smaller sizes."""
    return _use("llvm_ad_rgb" if LLVM_OK else "scalar_rgb")
