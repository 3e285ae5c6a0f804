"""`shiptrial detect` on a recording loads neither scipy.signal nor scipy.stats: importing
scipy.signal costs about 2 s of CPU (it imports scipy.stats), half of the command on one 500 s
recording (issue 25's 1 s target); the filters it needs are primitives.iir / savgol / spectrum."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_detect_path_imports_no_scipy_signal_or_stats() -> None:
    code = (
        "import sys\n"
        "import cli.detect_cmd, identify.detect.api, identify.detect.batch, identify.detect.verdict\n"
        "import primitives.zerophase, identify.yawid.estimate\n"
        "print(sorted(m for m in sys.modules if m.startswith(('scipy.signal', 'scipy.stats'))))\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code],
        cwd=ROOT,
        env={"PYTHONPATH": str(ROOT), "PATH": ""},
        capture_output=True,
        text=True,
        check=True,
    )
    assert out.stdout.strip() == "[]", out.stdout
