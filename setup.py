"""Build step beside pyproject.toml (which holds all the metadata): a plain, non-editable ``pip
install .`` also installs the shipped networks and missions, copied from the repository's
``models/`` and ``missions/`` into the package as ``mission/data/models`` and
``mission/data/missions`` (``mission.shipped`` finds them). Editable installs skip the copy: they
read the checkout's folders directly."""

from __future__ import annotations

import shutil
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

ROOT = Path(__file__).resolve().parent
SHIPPED = {"models": ("*.onnx", "*.json"), "missions": ("*.yaml",)}  # folder -> files installed


class BuildPyWithShipped(build_py):
    """``build_py`` that also copies the shipped folders into the built package."""

    def run(self) -> None:
        super().run()
        if getattr(self, "editable_mode", False):
            return
        for folder, patterns in SHIPPED.items():
            files = sorted(f for pat in patterns for f in (ROOT / folder).glob(pat))
            if not files:
                raise SystemExit(
                    f"setup.py: nothing to ship in {ROOT / folder} ({', '.join(patterns)})"
                )
            dest = Path(self.build_lib) / "mission" / "data" / folder
            dest.mkdir(parents=True, exist_ok=True)
            for f in files:
                shutil.copy2(f, dest / f.name)


setup(cmdclass={"build_py": BuildPyWithShipped})
