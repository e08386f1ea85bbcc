"""Build of the C kernels (cext/) as the extension module algos._kernels.

Environment switches:
  HFTRACE_DEBUG=1     -O0 -g and the kernels' invariant checks (HF_DEBUG)
  HFTRACE_SANITIZE=1  HFTRACE_DEBUG plus AddressSanitizer and UndefinedBehaviorSanitizer
                      (run Python with LD_PRELOAD of libasan; see `make sanitize`)
  HFTRACE_FUZZ=1      the fuzzing copy (`make fuzz`): clang (CC and LDSHARED default to it),
                      -O1 -g, the kernels' invariant checks, and
                      -fsanitize=fuzzer-no-link,address,undefined, so libFuzzer (atheris) gets
                      coverage from the C code itself; run Python with LD_PRELOAD of
                      atheris' asan_with_fuzzer.so, which supplies the sanitizer runtime and
                      the coverage callbacks
Otherwise: -O3, C99, no fast-math (the float kernels must round as IEEE 754 says).

The optional C Embree 3 peer (cext/peers/embree3_peer.c, algos._embree3) is added only where
embree3/rtcore.h is found (Debian: apt-get install libembree-dev; EMBREE_DIR=prefix for
another install); it is an optional extension, so a failure to build it is a warning and
never fails the build. Without it the peer's tests skip.
"""
import glob
import os
import sys

import numpy
from setuptools import Extension, setup

# The C sources are found, never listed: every .c file under cext/ is part of
# algos._kernels, except those of cext/peers/ (each peer is its own optional extension).
# Folders, lowest layer first (tests/project/test_c_layers.py checks that no file calls up):
# core, surfaces, walks, hierarchies, dispatch, terrain, raster, binding; peers apart.
PEERS = os.path.join("cext", "peers")
SOURCES = sorted(path for path in glob.glob(os.path.join("cext", "**", "*.c"), recursive=True)
                 if not path.startswith(PEERS + os.sep))
HEADERS = sorted(glob.glob(os.path.join("cext", "**", "*.h"), recursive=True))

compile_args = ["-std=c99", "-Wall", "-Wextra", "-Wno-unused-function"]
link_args = []
macros = [("NPY_NO_DEPRECATED_API", "NPY_1_7_API_VERSION")]
if os.environ.get("HFTRACE_DEBUG") == "1" or os.environ.get("HFTRACE_SANITIZE") == "1":
    compile_args += ["-O0", "-g", "-UNDEBUG"]
    macros.append(("HF_DEBUG", "1"))
else:
    compile_args += ["-O3"]
if os.environ.get("HFTRACE_FUZZ") == "1":
    # coverage instrumentation (sancov) for libFuzzer, without linking libFuzzer itself:
    # atheris brings it, preloaded with its ASan runtime
    os.environ.setdefault("CC", "clang")
    os.environ.setdefault("LDSHARED", "clang -shared")
    fuzz = ["-fsanitize=fuzzer-no-link,address,undefined", "-fno-sanitize-recover=undefined",
            "-fno-wrapv", "-fno-omit-frame-pointer"]
    compile_args = [a for a in compile_args if a != "-O3"] + ["-O1", "-g", "-UNDEBUG"] + fuzz
    link_args += ["-fsanitize=address,undefined"]
    if ("HF_DEBUG", "1") not in macros:
        macros.append(("HF_DEBUG", "1"))
if os.environ.get("HFTRACE_SANITIZE") == "1":
    sanitize = ["-fsanitize=address,undefined", "-fno-sanitize-recover=undefined", "-fno-wrapv",
                "-fno-omit-frame-pointer"]
    compile_args += sanitize
    link_args += sanitize
if sys.platform.startswith("linux"):
    # clock_gettime lives in librt on old glibc
    link_args.append("-lrt")



def _embree3_include():
    """The include directory holding embree3/rtcore.h, or None."""
    prefixes = [os.environ.get("EMBREE_DIR", ""), sys.prefix, "/usr/local", "/usr", "/opt/homebrew"]
    for prefix in filter(None, prefixes):
        if os.path.exists(os.path.join(prefix, "include", "embree3", "rtcore.h")):
            return os.path.join(prefix, "include")
    return None


def _optional_extensions():
    include = _embree3_include()
    if include is None:
        return []
    lib = os.path.join(os.path.dirname(include), "lib")
    return [Extension("algos._embree3", sources=[os.path.join(PEERS, "embree3_peer.c")],
                      include_dirs=[include], library_dirs=[lib], libraries=["embree3"],
                      extra_compile_args=compile_args, extra_link_args=link_args,
                      optional=True)]


setup(
    ext_modules=[
        Extension(
            "algos._kernels",
            sources=SOURCES,
            include_dirs=["cext", numpy.get_include()],
            define_macros=macros,
            extra_compile_args=compile_args,
            extra_link_args=link_args,
            depends=HEADERS,
        )
    ] + _optional_extensions()
)
