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

import sys

from ptpspeed7_ab import main  # benchmarks/tools

if __name__ == "__main__":
    if len(sys.argv) not in (3, 4, 5):
        sys.exit(__doc__)
    sk = sys.argv[3] if len(sys.argv) >= 4 else "both"
    main(int(sys.argv[1]), int(sys.argv[2]), ("paper", "real") if sk == "both" else (sk,),
         sys.argv[4] if len(sys.argv) == 5 else None)
