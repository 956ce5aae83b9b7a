"""Start-up of the command line: importing it loads none of scipy's heavy modules (ndimage, spatial,
interpolate, optimize) nor numba; each costs every command a tenth of a second or more, and they are imported
where a codec or reader uses them."""

from __future__ import annotations

import subprocess
import sys

HEAVY = ("scipy.ndimage", "scipy.spatial", "scipy.interpolate", "scipy.optimize", "numba", "sklearn", "scipy.cluster")


def test_importing_the_command_line_loads_no_heavy_module() -> None:
    code = f"import sys, mocapz.cli.main; print([m for m in {HEAVY!r} if m in sys.modules])"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]", out.stdout
