"""Where triangle_voting's kernel spends its interleaved time, by ``perf`` samples (issue #25, tvspeed7; Linux).

    perf record -e cpu-clock -F 10000 -o /tmp/tv.data python benchmarks/tools/tvspeed7_perf.py run [SKY] [R] [OUT]
    perf script -i /tmp/tv.data -F ip > /tmp/tv.ips
    python benchmarks/tools/tvspeed7_perf.py report /tmp/tv.ips [OUT] [TOP]

``run``: Table 6's images of SKY (``real``; seed 0, 200 of them), R (5) rounds, every registered plugin identifying
each image in turn as the benchmark does (so triangle voting's calls are cold); writes the executable mapping holding
``identify_flat``'s machine code to ``OUT`` (``/tmp/tv_code``: ``.bin`` and ``.addr``, its start address), and
prints triangle voting's median us. ``perf`` samples without hardware counters (``cpu-clock``), so a wait shows up
as the instruction it stalls (or the next one). ``report``: the sampled addresses within that mapping, disassembled
with ``objdump``: the share of each 512-byte block of code and the TOP (25) instructions.
"""

from __future__ import annotations

import collections
import ctypes
import re
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))


def run(sky: str, rounds: int, out: str) -> None:
    from starid_algorithms.triangle_voting.kernels import identify_flat

    from benchmarks.test_ratios import NAMES, TABLE6_SIM
    from starid import SKIES, Camera, SimConfig, Simulator, load_hipparcos
    from starid.registry import get_algorithm

    plugins = [get_algorithm(x)() for x in NAMES]
    cat, cam = load_hipparcos(), Camera()
    trials = Simulator(cat, cam, SimConfig(**{**TABLE6_SIM, **SKIES[sky]}), seed=0).generate(200)
    obs = [trials.observation(i, truth=False) for i in range(len(trials))]
    dbs = [a.build(cat, cam) for a in plugins]
    for a, d in zip(plugins, dbs, strict=True):
        a.identify(d, obs[0])
    cres = identify_flat.overloads[identify_flat.signatures[0]]
    addr = cres.library.get_pointer_to_function(cres.fndesc.llvm_func_name)
    for line in Path("/proc/self/maps").read_text().splitlines():
        lo, hi = (int(x, 16) for x in line.split()[0].split("-"))
        if lo <= addr < hi:
            Path(out + ".bin").write_bytes(ctypes.string_at(lo, hi - lo))
            Path(out + ".addr").write_text(hex(lo))
    k_tv = NAMES.index("triangle_voting")
    tv = []
    for _ in range(rounds):
        for o in obs:
            for j, (a, d) in enumerate(zip(plugins, dbs, strict=True)):
                t0 = time.perf_counter_ns()
                a.identify(d, o)
                if j == k_tv:
                    tv.append((time.perf_counter_ns() - t0) * 1e-3)
    print(f"triangle_voting median {np.median(tv):.1f} us; code mapping at {Path(out + '.addr').read_text()}")


def report(ips: str, out: str, top: int) -> None:
    lo = int(Path(out + ".addr").read_text(), 16)
    hi = lo + Path(out + ".bin").stat().st_size
    samples = collections.Counter()
    for line in Path(ips).read_text().splitlines():
        if line.strip():
            ip = int(line.split()[0], 16)
            if lo <= ip < hi:
                samples[ip - lo] += 1
    n = sum(samples.values())
    dis = subprocess.run(["objdump", "-D", "-b", "binary", "-mi386:x86-64", f"--adjust-vma={lo:#x}", out + ".bin"],
                         capture_output=True, text=True, check=True).stdout
    text = {}
    for line in dis.splitlines():
        m = re.match(r"\s*([0-9a-f]+):\s+(?:[0-9a-f]{2} )+\s*(.*)", line)
        if m:
            text[int(m.group(1), 16) - lo] = m.group(2)
    print(f"{n} samples in identify_flat's code")
    blocks = collections.Counter()
    for a, v in samples.items():
        blocks[a // 512 * 512] += v
    for a, v in blocks.most_common(12):
        print(f"  block {a:#7x} {v:6d} {100 * v / n:5.1f} %")
    for a, v in samples.most_common(top):
        print(f"  {a:#7x} {v:6d} {100 * v / n:5.1f} %  {text.get(a, '?')}")


if __name__ == "__main__":
    if len(sys.argv) < 2 or sys.argv[1] not in ("run", "report"):
        sys.exit(__doc__)
    if sys.argv[1] == "run":
        run(sys.argv[2] if len(sys.argv) > 2 else "real", int(sys.argv[3]) if len(sys.argv) > 3 else 5,
            sys.argv[4] if len(sys.argv) > 4 else "/tmp/tv_code")
    else:
        report(sys.argv[2], sys.argv[3] if len(sys.argv) > 3 else "/tmp/tv_code",
               int(sys.argv[4]) if len(sys.argv) > 4 else 25)
