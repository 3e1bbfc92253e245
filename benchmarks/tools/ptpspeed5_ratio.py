"""ptp's median per image against tetra's as ``benchmarks/test_ratios.py`` measures it (every registered
plugin identifies each image in turn, Table 6's settings), with another copy of the ptp plugin (e.g. the
base commit's, from ``git archive``) timed in the same rounds: before and after in one run (issue #25).

    python benchmarks/tools/ptpspeed5_ratio.py N_IMAGES ROUNDS [paper|real|both] [BASE_PTP_DIR]

``BASE_PTP_DIR`` is a directory holding another version of ``algorithms/ptp`` (its ``__init__.py``), loaded
as the package ``ptp_base``; it is called right after this checkout's ptp in each turn, and the two swap
places on every other image so neither always follows the other.

Since the eighth round the loop lives in ``ptpspeed7_ab.py``, which also prints the paired difference per image;
this name stays for the commands quoted on docs/algorithms/ptp.md.
"""

from __future__ import annotations

import runpy
from pathlib import Path

if __name__ == "__main__":   # the same arguments and output (plus the paired difference)
    runpy.run_path(str(Path(__file__).with_name("ptpspeed7_ab.py")), run_name="__main__")
