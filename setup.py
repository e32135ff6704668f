"""Build and install linkage_monitor with its ROS 2 messages in one `pip install`.

The messages in msg/ are generated with rosidl (CMake, the ROS 2 wheels from PyPI in the environment)
during `build_py`: the generated `linkage_monitor.msg` package and its typesupport
libraries are placed beside the hand-written Python package, and the staged `lib/` and
`share/` trees (shared libraries, .msg files, ament index) are installed into the
environment's prefix through `data_files`. Install with the build inputs already in the
environment: `pip install --no-build-isolation -e .` (see the Makefile).
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

from setuptools import Distribution, find_packages, setup
from setuptools.command.build_py import build_py

ROOT = Path(__file__).resolve().parent
PACKAGE = "linkage_monitor"
# one build tree per environment: each venv holds its own ROS 2 distribution
BUILD = ROOT / "build" / f"rosidl{Path(sys.prefix).name.removeprefix('.venv')}"
STAGE = BUILD / "stage"
GENERATED = ROOT / PACKAGE / "msg"
# can_msgs/msg/Frame (ros2_socketcan's /from_can_bus): no wheel exists, built here from its public
# definition (interfaces/can_msgs) into the Python package can_msgs beside linkage_monitor
CAN_MSGS_SOURCE = ROOT / "interfaces" / "can_msgs"
CAN_MSGS = ROOT / "can_msgs"


def _run(cmd: list[str], env: dict[str, str], cwd: Path, log: Path) -> None:
    with log.open("w") as out:
        proc = subprocess.run(cmd, cwd=cwd, env=env, stdout=out, stderr=subprocess.STDOUT)
    if proc.returncode != 0:
        sys.stderr.write(log.read_text()[-4000:])
        raise SystemExit(f"message generation failed: {' '.join(cmd)} (log: {log})")


def generate_messages(source: Path, package: str, build: Path, target: Path) -> None:
    """Run rosidl on ``source``'s msg/ via CMake into build/rosidl/stage and copy the Python side of
    ``package`` (its generated msg/ and typesupport modules) into ``target``."""
    prefix = Path(sys.prefix)
    # CMake refuses exported include paths inside the source dir, and the venv lives in
    # the repository: configure from a copy of the interface sources under build/.
    src = build / "src"
    src.mkdir(parents=True, exist_ok=True)
    for name in ("CMakeLists.txt", "package.xml"):
        shutil.copy2(source / name, src / name)
    shutil.copytree(source / "msg", src / "msg", dirs_exist_ok=True)
    env = dict(os.environ)
    env["AMENT_PREFIX_PATH"] = str(prefix)
    env["CMAKE_PREFIX_PATH"] = str(prefix)
    env["PATH"] = f"{prefix / 'bin'}{os.pathsep}{env.get('PATH', '')}"
    cmake = shutil.which("cmake", path=env["PATH"]) or "cmake"
    work = build / "cmake"
    work.mkdir(parents=True, exist_ok=True)
    if not (work / "build.ninja").exists():
        _run([cmake, str(src), "-G", "Ninja", f"-DCMAKE_INSTALL_PREFIX={STAGE}",
              f"-DPython3_EXECUTABLE={sys.executable}", "-DBUILD_TESTING=OFF",
              "-DLINKAGE_MONITOR_MSGS_ONLY=ON"], env, work, build / "configure.log")
    _run([cmake, "--build", ".", "--target", "install"], env, work, build / "build.log")
    site = next(STAGE.glob(f"lib/python*/site-packages/{package}"))
    target.mkdir(exist_ok=True)
    shutil.rmtree(target / "msg", ignore_errors=True)
    shutil.copytree(site / "msg", target / "msg",
                    ignore=shutil.ignore_patterns("*.c", "__pycache__"))
    for lib in site.glob("*.so"):
        shutil.copy2(lib, target / lib.name)
    if not (target / "__init__.py").exists():   # can_msgs: the generated package whole (linkage_monitor has its own)
        shutil.copy2(site / "__init__.py", target / "__init__.py")


def staged_data_files() -> list[tuple[str, list[str]]]:
    """The staged lib/*.so and share/ tree as (install dir, files) pairs for data_files."""
    files: dict[str, list[str]] = {}
    for path in sorted(STAGE.rglob("*")):
        rel = path.relative_to(STAGE)
        if path.is_dir() or rel.parts[0] not in ("lib", "share"):
            continue
        if rel.parts[0] == "lib" and (len(rel.parts) != 2 or path.suffix != ".so"):
            continue  # the Python side is shipped as package files
        files.setdefault(str(rel.parent), []).append(str(path.relative_to(ROOT)))
    return sorted(files.items())


class BuildWithMessages(build_py):
    """build_py that first generates linkage_monitor.msg from msg/*.msg."""

    def run(self) -> None:
        generate_messages(ROOT, PACKAGE, BUILD, ROOT / PACKAGE)
        generate_messages(CAN_MSGS_SOURCE, "can_msgs", BUILD / "can_msgs", CAN_MSGS)
        self.distribution.data_files = staged_data_files()
        super().run()


class PlatformDistribution(Distribution):
    """The package ships compiled typesupport libraries: a platform wheel with data."""

    def has_ext_modules(self) -> bool:
        return True

    def has_data(self) -> bool:
        return True


GENERATED.mkdir(exist_ok=True)  # filled by build_py; must exist for the metadata step
(CAN_MSGS / "msg").mkdir(parents=True, exist_ok=True)
setup(
    name=PACKAGE,
    version="0.3.0",
    description="Live hinge reactions, lift capacity and steerability of tractor linkages (ROS 2)",
    packages=sorted({*find_packages(include=[PACKAGE, f"{PACKAGE}.*"]), f"{PACKAGE}.msg", "can_msgs", "can_msgs.msg"}),
    package_data={PACKAGE: ["*.so"], f"{PACKAGE}.mechanics.presets": ["*.yaml"],
                  f"{PACKAGE}.mechanics.implements": ["*.yaml"], "can_msgs": ["*.so"]},
    data_files=[],
    python_requires=">=3.10",
    distclass=PlatformDistribution,
    cmdclass={"build_py": BuildWithMessages},
    entry_points={
        "console_scripts": [
            "linkage-monitor = linkage_monitor.cli.main:main",
            "linkage_monitor_node = linkage_monitor.ros.node:main",
            "linkage_monitor_lifecycle_node = linkage_monitor.ros.lifecycle_node:main",
        ],
    },
)
