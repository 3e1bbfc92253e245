"""``lptspeed6_stages.py`` on the kernel of branch lptspeed7 (issue #25): the same stage table.

    python benchmarks/tools/lptspeed7_stages.py SKY N ROUNDS EVICT

The image-side pigeonhole is ``image_groups_pad`` since lptspeed7; this tool swaps that one patch
of ``lptspeed3_stages.PATCHES`` and runs ``lptspeed6_stages.main`` (arguments as there).
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import lptspeed6_stages  # noqa: E402

OLD = ("                        if not image_groups_at(chars, g, image, by_level_x, nz - need, pattern2, valid, xs, "
       "groups):\n                            continue\n")
NEW = ("                        if not image_groups_pad(chars, g, nz, width, pad_t, pad_x, nz - need, pattern2, "
       "valid, xs,\n                                                groups):\n                            continue\n")
NEW_TIMED = ("                        ca = cycles()\n"
             "                        ok_ = image_groups_pad(chars, g, nz, width, pad_t, pad_x, nz - need, pattern2, "
             "valid, xs, groups)\n"
             "                        trace[9] += cycles() - ca\n"
             "                        if not ok_:\n                            continue\n")

if __name__ == "__main__":
    if len(sys.argv) != 5:
        sys.exit(__doc__)
    patches = lptspeed6_stages.PATCHES
    i = next(k for k, (old, _) in enumerate(patches) if old == OLD)
    patches[i] = (NEW, NEW_TIMED)
    lptspeed6_stages.main(sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), sys.argv[4])
