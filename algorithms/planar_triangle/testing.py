"""Test helpers shared by the ``planar_triangle`` and ``triangle_voting`` test files (one copy, imported by both).

Not part of the algorithm: plain functions the two plugins' tests call with their own class and
database. Both plugins draw triangles in ``explain`` and size their windows from ``sigma_px``
with a 1 px floor (``sigma_window_px``).
"""

from __future__ import annotations

import numpy as np

from starid import Observation, SimConfig, Simulator
from starid.plugin import Explanation


def assert_sigma_follows_with_1px_floor(cls) -> None:
    """``sigma_px`` follows the simulator (None by default); the window is max(sigma_px, 1 px); pinned wins."""
    assert cls.follows == {"sigma_px": "sigma_px"}
    assert cls().sigma_px is None and cls().sigma_window_px == 1.0
    for world, window in ((0.0, 1.0), (0.5, 1.0), (1.0, 1.0), (3.0, 3.0)):
        alg = cls().resolved(SimConfig(sigma_px=world))
        assert alg.sigma_px == world and alg.sigma_window_px == window
    pinned = cls(sigma_px=2.0).resolved(SimConfig(sigma_px=0.0))
    assert pinned.sigma_px == 2.0 and pinned.sigma_window_px == 2.0


def assert_explain_draws_triangles(alg, db, catalog, camera) -> None:
    """On 4 noisy images: a captioned Explanation each; where stars are identified, at least one triangle
    (3 segments) inside the image and 3 highlighted stars (in at least 3 of the 4); a 2-star image too."""
    sim = Simulator(catalog, camera, SimConfig(sigma_px=1.0, sigma_mag=0.5), seed=8)
    n_drawn = 0
    for t in range(4):
        obs = sim.observation(t)
        ex = alg.explain(db, obs)
        assert isinstance(ex, Explanation) and ex.caption
        hip = alg.identify(db, obs).hip
        if np.any(hip >= 0):
            n_drawn += 1
            assert ex.segments.shape[0] >= 3 and ex.highlight.size >= 3
            assert np.all((ex.segments[..., 0] >= 0) & (ex.segments[..., 0] < camera.width_px))
    assert n_drawn >= 3
    tiny = Observation(np.array([10.0, 20.0]), np.array([10.0, 30.0]), np.array([3.0, 4.0]), camera)
    assert isinstance(alg.explain(db, tiny), Explanation)
