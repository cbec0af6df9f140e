"""Builds the extension module `evnerf` with CMake (EVNERF_PYTHON=ON, target evnerf_python) for the
interpreter running this script; pyproject.toml holds the metadata. See the README's Python section."""
import glob
import os
import pathlib
import shutil
import subprocess
import sys

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

SOURCE = pathlib.Path(__file__).resolve().parent


class CMakeBuild(build_ext):
    def build_extension(self, ext):
        target = pathlib.Path(self.get_ext_fullpath(ext.name)).resolve()
        build = pathlib.Path(self.build_temp).resolve() / "cmake"
        configure = ["cmake", "-S", str(SOURCE), "-B", str(build), "-DCMAKE_BUILD_TYPE=Release", "-DEVNERF_PYTHON=ON",
                     "-DEVNERF_BUILD_TESTS=OFF", "-DEVNERF_BUILD_EXAMPLES=OFF", f"-DPython_EXECUTABLE={sys.executable}"]
        if shutil.which("ninja"):
            configure += ["-G", "Ninja"]
        configure += os.environ.get("EVNERF_CMAKE_ARGS", "").split()
        subprocess.run(configure, check=True)
        subprocess.run(["cmake", "--build", str(build), "--target", "evnerf_python", "-j", str(os.cpu_count() or 1)], check=True)
        built = glob.glob(str(build / "examples" / "python" / ("evnerf" + "*.so")))
        if len(built) != 1:
            raise RuntimeError(f"expected one built module evnerf*.so in {build}/examples/python, found {built}")
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(built[0], target)


setup(ext_modules=[Extension("evnerf", sources=[])], packages=[], py_modules=[], cmdclass={"build_ext": CMakeBuild})
