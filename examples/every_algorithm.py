# %% [markdown]
# # Every registered algorithm: its reasoning on one image, and where it breaks
#
# The same simulated image for every algorithm starid has registered (trial 3 of seed 11, the
# paper's 1 px / 0.5 Mv world in the real sky), each drawn with its own `explain()`: which
# pattern it matched and how it decided. Then the same attitudes in harder and harder worlds:
# centroid noise from 0 to 3 px, and 0 to 6 false stars per image (hot pixels, planets), so you
# can see where each method stops naming the stars.
#
# Run it as a script: `python examples/every_algorithm.py` (pictures go to `gallery_out/`, or
# `$STARID_EXAMPLE_OUT`; `$STARID_EXAMPLE_TRIALS` images per world, 60 by default). The
# documentation site's gallery and algorithm pages show its pictures.

# %%
import os
from pathlib import Path

import pandas as pd

import starid
from starid import plots
from starid.harness import prepare, score
from starid.report.show import show

OUT = Path(os.environ.get("STARID_EXAMPLE_OUT", "gallery_out"))
OUT.mkdir(parents=True, exist_ok=True)
N = int(os.environ.get("STARID_EXAMPLE_TRIALS", "60"))
SEED, TRIAL = 11, 3
NAMES = starid.available()

catalog = starid.load_hipparcos()
camera = starid.Camera()                                # Zhou & Ye's Table 4 camera
base = starid.SimConfig(sigma_px=1.0, sigma_mag=0.5)   # 1 px / 0.5 Mv, the real sky

# %% [markdown]
# ## Each algorithm's reasoning on the same image
# One picture per algorithm: stars sized by brightness; circles are correct ids, squares missed,
# crosses wrong; the bold lines are what the algorithm's `explain()` says decided it.

# %%
prepared = {name: prepare(starid.get_algorithm(name)().resolved(base), catalog, camera, None, name)
            for name in NAMES}
world = {"sigma_px": base.sigma_px, "sigma_mag": base.sigma_mag}
for name in NAMES:
    shown = show([name], trial=TRIAL, seed=SEED, world=world, camera=camera, catalog=catalog,
                 databases={name: prepared[name].database})
    shown.figure.savefig(OUT / f"reasoning_{name}.png", dpi=110)
    print(shown.results[["label", "status", "n_correct", "n_wrong"]].to_string(index=False, header=False))

# %% [markdown]
# ## Where each breaks
# The identification rate (95 % Wilson band) on the same `N` attitudes in each world. Common
# random numbers: trial *k* has the same stars and the same unit noise at every noise level, so
# a curve's steps are the setting's, not the draw's.

# %%
def sweep(axis, values, **fixed):
    frames = []
    for value in values:
        config = starid.SimConfig(**{**world, **fixed, axis: value})
        trials = starid.Simulator(catalog, camera, config, seed=SEED).generate(N)
        for name in NAMES:
            algorithm = prepared[name].algorithm if axis != "sigma_px" else (
                starid.get_algorithm(name)().resolved(config))    # tolerances follow the world's noise
            ready = prepared[name] if axis != "sigma_px" else prepare(algorithm, catalog, camera, None, name)
            frames.append(score(ready, trials, catalog).assign(**{f"grid_{axis}": value}))
    return pd.concat(frames, ignore_index=True)


noise = sweep("sigma_px", [0.0, 1.0, 2.0, 3.0])
plots.rate_curve(noise, "sigma_px", title=f"identification rate vs centroid noise ({N} images per point)") \
    .savefig(OUT / "breaks_noise.png", dpi=110)
false = sweep("false_stars", [0, 2, 4, 6])
plots.rate_curve(false, "false_stars", title=f"identification rate vs false stars, 1 px noise ({N} images per point)") \
    .savefig(OUT / "breaks_false_stars.png", dpi=110)
print(starid.summarize(pd.concat([noise.assign(world="noise"), false.assign(world="false")]),
                       by=("world", "label"))[["world", "label", "id_rate"]].to_string(index=False))

# %%
assert all((OUT / f"reasoning_{name}.png").is_file() for name in NAMES)
assert (OUT / "breaks_noise.png").is_file() and (OUT / "breaks_false_stars.png").is_file()
