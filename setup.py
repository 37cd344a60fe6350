"""Build hook: the wheel carries copies of the top-level `models/` and `diagrams/` folders.

They are the sources the design names (the platforms' URDFs and platform files, and the
scenario files); at build time
they are copied into the package as `mca_drake/data/models` and `mca_drake/data/diagrams`,
where `mca_drake.resources` finds them in an installed package. Everything else about the
build is in pyproject.toml.
"""

from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

ROOT = Path(__file__).resolve().parent
# top-level folder -> the file patterns the wheel carries from it
PACKAGED_FOLDERS = {"models": ("*.urdf", "*.yaml"), "diagrams": ("*.yaml",)}


class BuildPyWithPackagedFolders(build_py):
    """build_py that also copies models/ and diagrams/ into mca_drake/data/."""

    def run(self):
        super().run()
        for folder, patterns in PACKAGED_FOLDERS.items():
            sources = sorted(p for pattern in patterns for p in (ROOT / folder).glob(pattern))
            if not sources:
                raise RuntimeError(f"{ROOT / folder} holds no {patterns}: the wheel needs them")
            target = Path(self.build_lib) / "mca_drake" / "data" / folder
            self.mkpath(str(target))
            for source in sources:
                self.copy_file(str(source), str(target / source.name))


setup(cmdclass={"build_py": BuildPyWithPackagedFolders})
