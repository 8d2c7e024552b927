"""The one packaging fact pyproject.toml cannot state: the scene library lives in ``scenes/`` at the
top of the repository and is installed inside the package as ``pbrbench/scenes`` (setuptools'
``package_dir`` maps it at build time; nothing is copied by hand).  Everything else is in
pyproject.toml."""

from setuptools import find_namespace_packages, setup

setup(
    packages=find_namespace_packages(include=["pbrbench", "pbrbench.*"], exclude=["*.__pycache__"]) + ["pbrbench.scenes"],
    package_dir={"pbrbench.scenes": "scenes"},
    package_data={"pbrbench": ["report/templates/*.html", "report/templates/*.css", "bench/noise_scales.json"],
                  "pbrbench.scenes": ["*.toml", "*.md", "*.npy"]},
)
