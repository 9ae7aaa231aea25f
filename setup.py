# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""setuptools driver: build_ext runs CMake to build the pybind11 extension ds3d._ds3d.

Works offline with Debian's packages (no PyPI): /usr/bin/python3 -m pip install --no-build-isolation .
Environment: DS3D_CMAKE_ARGS (extra CMake arguments), DS3D_BUILD_SLAM=0 (core only).
"""
import os
import pathlib
import re
import shlex
import subprocess
import sys

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

ROOT = pathlib.Path(__file__).resolve().parent


def read_version():
    text = (ROOT / "include/ds3d/version.hpp").read_text()
    parts = [re.search(rf"#define DS3D_VERSION_{p} (\d+)", text).group(1)
             for p in ("MAJOR", "MINOR", "PATCH")]
    return ".".join(parts)


class CMakeExtension(Extension):
    def __init__(self, name):
        super().__init__(name, sources=[])


class CMakeBuild(build_ext):
    def build_extension(self, ext):
        extdir = pathlib.Path(self.get_ext_fullpath(ext.name)).resolve().parent
        build_temp = pathlib.Path(self.build_temp).resolve() / "cmake"
        build_temp.mkdir(parents=True, exist_ok=True)
        args = [
            f"-DCMAKE_BUILD_TYPE={'Debug' if self.debug else 'Release'}",
            f"-DPython_EXECUTABLE={sys.executable}",
            f"-DDS3D_PYTHON_OUTPUT_DIR={extdir}",
            "-DDS3D_PYTHON_SKIP_COPY=ON",
            "-DDS3D_BUILD_PYTHON=ON", "-DDS3D_BUILD_TESTS=OFF", "-DDS3D_BUILD_BENCH=OFF",
            "-DDS3D_BUILD_TOOLS=OFF",
            f"-DDS3D_BUILD_SLAM={'OFF' if os.environ.get('DS3D_BUILD_SLAM') == '0' else 'ON'}",
        ] + shlex.split(os.environ.get("DS3D_CMAKE_ARGS", ""))
        subprocess.run(["cmake", "-S", str(ROOT), "-B", str(build_temp)] + args, check=True)
        jobs = os.environ.get("CMAKE_BUILD_PARALLEL_LEVEL", str(os.cpu_count() or 1))
        subprocess.run(["cmake", "--build", str(build_temp), "--target", "_ds3d", "-j", jobs],
                       check=True)


setup(
    version=read_version(),
    ext_modules=[CMakeExtension("ds3d._ds3d")],
    cmdclass={"build_ext": CMakeBuild},
    zip_safe=False,
    # Keep setuptools' own build tree inside CMake's build/ (reused by later installs).
    options={"build": {"build_base": "build/setuptools"}},
)
