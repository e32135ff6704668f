"""Screenshots of the real Rerun viewer (headless: xvfb + the software Vulkan driver) and the
pixel check that the side view draws the linkage."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np

RERUN = Path(sys.executable).with_name("rerun")


def screenshot(rrd: Path, work: Path, timeout: float = 150.0, blueprint: Path | None = None) -> np.ndarray:
    """RGB (H, W, 3) in 0..255 of the viewer opening ``rrd`` (window 1200x700) in its default
    blueprint, or in the blueprint file ``blueprint`` (.rbl) when given."""
    import matplotlib.image as mpimg

    work.mkdir(parents=True, exist_ok=True)
    shot = work / f"{rrd.stem}.png"
    env = dict(os.environ, HOME=str(work), XDG_RUNTIME_DIR=str(work), XDG_DATA_HOME=str(work / "data"),
               XDG_CONFIG_HOME=str(work / "config"))
    os.chmod(work, 0o700)
    # screen larger than the window: the X pointer (screen centre) stays off the viewer, no hover tooltip;
    # --port auto: a viewer of its own (without it, a viewer another test has open on the default port
    # is handed the file, and this one exits without a screenshot)
    files = [str(rrd)] if blueprint is None else [str(rrd), str(blueprint)]
    run = subprocess.run(["xvfb-run", "-a", "-s", "-screen 0 2560x1600x24", str(RERUN), *files,
                          "--screenshot-to", str(shot), "--window-size", "1200x700", "--port", "auto"],
                         env=env, capture_output=True, timeout=timeout, check=True)
    if not shot.is_file():   # the viewer exits 0 without one when it cannot take it: say what it printed
        tail = (run.stdout + run.stderr).decode(errors="replace")[-2000:]
        raise AssertionError(f"the viewer wrote no screenshot {shot}; its output ends:\n{tail}")
    return mpimg.imread(shot)[..., :3] * 255.0


def pixels_of(rgb: np.ndarray, color: tuple[int, int, int], left_share: float = 0.6, tol: float = 12.0) -> int:
    """How many pixels of ``color`` the left ``left_share`` of the window holds (the linkage's 2D
    view fills the left 3/5 in the default blueprint)."""
    side = rgb[:, : int(rgb.shape[1] * left_share)]
    return int((np.abs(side - np.array(color)).max(axis=-1) < tol).sum())
