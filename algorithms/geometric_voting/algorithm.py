"""The geometric-voting plugin class (Kolomenkin et al. 2008): parameters, build, identify, explain."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, fields
from functools import lru_cache
from typing import ClassVar

import numpy as np
from starid_algorithms.pyramid.algorithm import (
    PairDatabase,
    build_pair_database,
    check_pair_params,
    d_min_for,
    pair_limit_rad,
    window_eps,
)
from starid_algorithms.pyramid.kernels import PairTol

from starid.camera import REFERENCE_CAMERA, Camera
from starid.catalog import Catalog
from starid.errors import ConfigError
from starid.kernels import Frame, camera_frame, rad_to_chord
from starid.observation import Observation
from starid.params import check_flag, check_number, check_whole, param
from starid.plugin import Algorithm, Explanation, Identification

from .kernels import WORK_COUNTERS, VoteRule, tally_like, voting_kernel

#: the guide limit chosen on :data:`starid.camera.REFERENCE_CAMERA` (Table 4: 10 x 10 deg, 1024 x 1024 px)
REF_MAG_LIMIT = 6.0


def reference_chance_window(camera: Camera, max_pair_deg: float) -> float:
    """The pair window (radians) at which V <= 6.0 guide stars would collect, on ``camera``, the chance
    votes per image pair they collect on the reference camera at its 1 px window: chance votes grow
    as n eps c_max, so this is eps_ref (c_max_ref / c_max). :func:`derived_mag_limit` and
    :func:`derived_vote_window` hold the chance level with it, one by the guide limit, the other by
    the voting window."""
    return window_eps(REFERENCE_CAMERA, None, 3.0) * (pair_limit_rad(REFERENCE_CAMERA, max_pair_deg)
                                                      / pair_limit_rad(camera, max_pair_deg))


def derived_mag_limit(catalog: Catalog, camera: Camera, max_pair_deg: float, sigma_px: float | None = None,
                      beta: float = 3.0) -> float:
    """``mag_limit`` = None: the faintest guide limit (at most 6.0) at which a catalog star collects
    no more chance votes per image pair than V <= 6.0 gives on the reference camera at its 1 px window.

    A catalog star with neighbours at n per steradian gets a chance vote from an image pair at
    separation c when one of them falls in the annulus c +- eps: 4 pi n eps c on average (the
    model ``expected_votes`` subtracts). eps is the pair window (pyramid's :func:`window_eps`:
    ``beta`` sqrt(2) max(``sigma_px``, 1 px) / f_px) and c scales with the pair limit c_max, so
    the chance votes are proportional to n eps c_max, and the guide stars may number
    N_6 (eps_ref / eps) (c_max_ref / c_max), N_6 = the catalog's stars with V <= 6.0, eps_ref the
    reference camera's 1 px window: the limit is the V of that many-th brightest star. It never
    exceeds 6.0 (the guide stars must be detectable; a narrower field keeps 6.0). On the reference
    camera at 1 px of noise or less it is exactly 6.0; more centroid noise widens eps, so lowers it
    (the reference camera at 2 px: V <= 5.39; a 20 deg, 1024 px camera: V <= 5.07 at 1 px, 4.47 at 2 px).

    The default ``mag_limit`` is this limit at the 1 px floor (``sigma_px`` None): the guide stars
    are not cut for centroid noise, which would leave too few of them in the field (at 2 px on the
    20 deg camera, V <= 4.47 leaves 11 of 100 images with fewer than 4 usable guide stars); where
    the guide stars are fainter than the limit at the actual window, the ranking counts the
    chance votes with their saturation instead (:func:`derived_saturate`).
    """
    v = np.sort(np.asarray(catalog.v_mag, dtype=np.float64))
    n_ref = int(np.searchsorted(v, REF_MAG_LIMIT, side="right"))
    scale = reference_chance_window(camera, max_pair_deg) / window_eps(camera, sigma_px, beta)
    k = int(round(scale * n_ref))
    if k >= n_ref:
        return REF_MAG_LIMIT
    return float(v[max(k, 3) - 1])


def derived_saturate(catalog: Catalog, camera: Camera, mag_limit: float, max_pair_deg: float,
                     sigma_px: float | None, beta: float) -> bool:
    """``saturate_votes`` = None: True when the guide stars (V <= ``mag_limit``) are fainter than
    :func:`derived_mag_limit` allows at the actual window, i.e. when a catalog star collects more
    chance votes per image pair than on the reference camera at 1 px.

    ``expected_votes`` subtracts the linear expectation ``degree * sum_b p_b`` of the chance votes.
    With ``once_per_pair`` an image pair gives a catalog star at most one vote, so the true
    expectation is ``sum_b 1 - exp(-degree p_b)``: the linear one overestimates it, most for the
    stars with many neighbours, and once ``degree p_b`` approaches 1 it exceeds the number of
    image pairs -- a true star with all its votes is then ranked below chance stars with fewer
    neighbours. The linear model is kept where chance votes are at or below the reference level
    (where it was chosen, and where Table 4 was measured), the saturating one is used beyond it.
    False on the reference camera at 1 px of noise or less, and on any camera at the 1 px floor
    with the derived ``mag_limit``; True e.g. at 2 px on a 20 deg, 1024 px camera (V <= 5.07
    against 4.47 allowed).
    """
    return mag_limit > derived_mag_limit(catalog, camera, max_pair_deg, sigma_px, beta)


#: the voting window is never narrower than this many standard deviations of the chord error
#: (sqrt(2) sigma): the true votes over the chance votes' spread, erf(w / (sqrt(2) s)) / sqrt(w), peaks
#: at w = 1.40 s (a narrower window loses more true votes than it removes chance ones)
VOTE_WINDOW_SIGMAS = 1.4


def derived_vote_window(catalog: Catalog, camera: Camera, mag_limit: float, max_pair_deg: float,
                        sigma_px: float | None, beta: float) -> float:
    """``vote_window_px`` = None: the half-width (px) of the pair windows that *vote*: the noise window
    eps narrowed to the window at which the guide stars (V <= ``mag_limit``) collect the reference
    chance votes (V <= 6.0 on the reference camera at its 1 px window), but never below the 1 px
    floor window nor below ``VOTE_WINDOW_SIGMAS`` standard deviations of the chord error.

    Chance votes per image pair grow as n eps c_max (n guide stars per steradian). When centroid
    noise widens eps beyond the 1 px floor, they grow with it: at 2 px on the reference camera a
    window holds about 2,000 catalog pairs and a catalog star gets a chance vote from about half of
    the image pairs, so a true star's full set of votes barely stands out. The voting window is
    therefore held at the chance level of the reference: eps_chance = eps_ref (N_6 / N) (c_max_ref
    / c_max), N the catalog's stars with V <= ``mag_limit``, N_6 those with V <= 6.0. It is only
    ever narrower than eps, and never narrower than eps at the 1 px floor, so nothing changes at
    1 px of noise or less on any camera. Verification, the shortlist agreement and the reprojection
    keep the full eps (they must accept every true pair). Reference camera at 2 px: 4.24 px
    instead of 8.49 px (1.5 standard deviations of the chord error, 87 % of the true votes kept).
    """
    v = np.asarray(catalog.v_mag, dtype=np.float64)
    n_ref = int(np.count_nonzero(v <= REF_MAG_LIMIT))
    n = max(int(np.count_nonzero(v <= mag_limit)), 1)
    eps = window_eps(camera, sigma_px, beta)
    eps_floor = window_eps(camera, None, beta)
    eps_chance = reference_chance_window(camera, max_pair_deg) * (n_ref / n)
    eps_optimal = window_eps(camera, sigma_px, VOTE_WINDOW_SIGMAS)
    return min(eps, max(eps_chance, eps_floor, eps_optimal)) * camera.f_px


@dataclass(frozen=True, eq=False)
class VotingDatabase(PairDatabase):
    """The Pyramid plugin's :class:`PairDatabase` (which keeps the double-star distance used) with
    the guide limit used (``mag_limit`` None: derived from the camera) and whether the ranking
    counts saturating chance votes (``saturate_votes`` None: derived, for the ``sigma_px`` it was
    built with), and the voting window (``vote_window_px`` None: derived, likewise; None in the
    database = the full eps)."""

    mag_limit: float = REF_MAG_LIMIT
    saturate_votes: bool = False
    vote_window_px: float | None = None


@dataclass(frozen=True)
class GeometricVoting(Algorithm):
    """Geometric voting: every image pair's angle votes for catalog stars, then pairwise verification.

    Kolomenkin M., Pollak S., Shimshoni I., Lindenbaum M., "Geometric voting algorithm for star
    trackers", IEEE Transactions on Aerospace and Electronic Systems 44(2):441-456, 2008. Full
    description, parameters and measurements: ``docs/algorithms/geometric_voting.md``.

    Database: every pair of guide stars (V <= ``mag_limit``) closer than the field's diagonal,
    keyed by its chord 2 sin(theta/2), with Mortari's k-vector -- the Pyramid plugin's database
    without the per-star lists, plus the ``mag_limit`` and ``d_min_deg`` actually used
    (:class:`VotingDatabase`).

    Camera-derived parameters (None = derived in ``build``; exactly V <= 6.0 and 0.05 deg on the
    default 10 deg Table 4 camera, :data:`starid.camera.REFERENCE_CAMERA`):

    * ``mag_limit``: a catalog star collects chance votes from an image pair at about
      4 pi n eps c (n guide stars per steradian, eps ~ the pixel angle, c ~ the pair limit
      c_max), so the guide stars are cut to N_6 (f_px / f_ref) (c_max_ref / c_max), N_6 = the
      catalog's stars with V <= 6.0, and never fainter than 6.0 (:func:`derived_mag_limit`). On
      Luo et al.'s 20 deg, 1024 px camera: V <= 5.07 -- with V <= 6.0 the chance vote per image
      pair rises from 0.30 (10 deg) to 0.68 and a median of 100 catalog stars tie or beat the
      true star's votes;
    * ``d_min_deg``: 0.05 deg scaled by the pixel angle, i.e. 5.1 px on every camera, at most 1 deg
      (pyramid's :func:`~starid_algorithms.pyramid.algorithm.d_min_for`); it must exceed eps (4.2 px at
      1 px) or a voter with a neighbour within eps cannot be confirmed by the reprojection (0.05 deg is
      2.6 px at 20 deg);
      in the image (not the catalog) the isolation radius is max(``d_min_deg``, eps), as in pyramid;
    * ``saturate_votes``: True when ``mag_limit`` is fainter than :func:`derived_mag_limit` allows at
      the actual window (eps with ``sigma_px``): chance votes then exceed the reference level and
      ``expected_votes`` counts them as sum_b 1 - exp(-degree p_b) (one vote per image pair at most)
      instead of the linear degree sum_b p_b, which exceeds the number of image pairs for
      well-connected stars and buries the true ones (:func:`derived_saturate`). False on the default
      camera at 1 px or less (Table 4 unchanged), True at 2 px on Luo's 20 deg camera;
    * ``vote_window_px``: the half-width of the windows that vote, eps narrowed to the window at
      which the guide stars collect the reference chance votes, never below the 1 px floor window
      nor 1.4 standard deviations of the chord error (:func:`derived_vote_window`): eps itself at
      1 px or less on every camera, 4.24 px instead of 8.49 px at 2 px on the default and on Luo's
      camera. Verification, the shortlist agreement and the reprojection keep the full eps;

    Identification (the paper's two rounds):

    1. voting: for every pair of image stars (i, j) the catalog pairs (I, J) whose angle lies
       within +-eps of theta_ij are found by a k-vector range query, and each adds a vote for I
       and for J to both i and j (``once_per_pair``: at most one vote per catalog star per
       image pair); each image star takes the catalog star with most votes (ties: the first
       maximum, left to verification) -- with ``n_candidates`` = 1 and ``expected_votes`` off;
    2. verification: two assignments (i -> I, j -> J) agree when |theta_ij - theta_IJ| <= eps;
       assignments with too little agreement are dropped (``starid.kernels.verify_pairwise``:
       each kept one agrees with at least ``min_support`` others and a fraction
       ``min_fraction`` of them);
    3. the attitude of the verified stars by Wahba's problem (``starid.kernels.wahba_rows``).

    Choices the paper leaves open or that are starid's (each a parameter):

    * eps = ``beta`` sqrt(2) sigma, sigma = max(``sigma_px``, 1 px) / f_px (reconstructed from
      the usual 3-sigma rule on an angle between two noisy directions; the 1 px floor gives a
      noise-free world a window; ``sigma_px`` follows the simulator when left None);
    * verification threshold: the paper keeps stars whose verification votes exceed a
      threshold; starid drops the least supported repeatedly until ``min_support`` = 2 and a
      majority (``min_fraction`` = 0.5) agree (reconstructed: one rule shared with the other
      plugins, and strict enough that random fields yield nothing);
    * ``once_per_pair`` (reconstructed, on by default; off = every matching catalog pair votes,
      as in LOST's implementation): in starid's 10 deg field at 1 px a window holds ~1,000
      catalog pairs, and a catalog star with many neighbours at about that distance collects
      several votes from one image pair; counted every time, such stars outvote the true one for
      4 image stars in 5, counted once per image pair for about 1 in 5;
    * ``expected_votes`` (reconstructed, on by default): a star is ranked by its votes minus the
      votes it would collect by chance, ``degree * w``, where ``degree`` is its number of
      catalog neighbours and ``w`` the probability that one neighbour falls in the windows of
      the image star's pairs (4 eps c / c_max^2 per pair: distances spread as in a disc). Dense
      sky otherwise wins on its many neighbours alone;
    * ``n_candidates`` (reconstructed, 16 by default; 1 = the paper): each star keeps its 16 best
      catalog stars and takes the one that agrees in pair angle with the most other stars'
      shortlists (the verification vote, counted over shortlists) -- in a 6-star image the true
      star has at most 5 votes, which chance alone often matches;
    * detections closer than ``d_min_deg`` to another, and guide stars with such a neighbour,
      are not used; only the ``max_stars`` (15) brightest detections vote (reconstructed: the
      cost grows as the square of the voters; in the deep sky 15 voters identify as many images
      as 40 (85 vs 86 %, seed 7) at a tenth of the time; with ``max_window`` it also keeps wide-angle cameras fast);
    * ``confirm_fraction``, ``min_extra`` (starid's extension; 0 and 0 switch it off): the
      verified stars' attitude must see this fraction of the guide stars it puts on the sensor
      and 3 + ``min_extra`` stars in all, else nothing is reported;
    * ``round_voters``, ``round_step`` (starid's extension, 5 and 1 by default; ``round_voters``
      0 = the paper's single round of all voters): the stars vote in rounds, the 5 brightest
      first; the first round whose choice passes verification and confirmation is reported, else
      the next star joins and its pairs add votes to the same counters (the last round has
      exactly the votes of a single round). In the paper's sky at 1 px / 0.5 Mv five voters
      decide 78 % of the images (seed 7), so most images cost 10 pair windows instead of up to
      105; chosen on seed 7 (5 against 4 and 6; steps of 1 against 2 and 5);
    * ``report_all`` (starid's extension, on by default; off = only the verified voters): every
      star the confirming reprojection identifies is reported, with the attitude refitted to
      them and the reprojection repeated once (as Pyramid does).

    The speed comes from how the votes are counted, not from a different method: one window is
    read once for both of its stars, counters are one uint8 row per voter, and the catalog stars
    reaching 3 votes are listed as they do so that ranking need not scan the whole catalog (exact;
    it falls back to the full scan when the list cannot settle the shortlist).
    """

    name: ClassVar[str] = "geometric_voting"
    #: the paper's voting: one candidate per star, raw vote counts, every pair votes, one round of every
    #: voter, only the voted stars reported (``geometric_voting:paper``)
    published: ClassVar[dict] = {"n_candidates": 1, "expected_votes": False, "once_per_pair": False,
                                 "round_voters": 0, "report_all": False}
    follows: ClassVar[dict] = {"sigma_px": "sigma_px"}

    mag_limit: float | None = param(
        None, unit="mag",
        help="guide stars have V <= this; None = derived from the camera (6.0 on Table 4, never fainter)")
    sigma_px: float | None = param(None, unit="px",
                                   help="centroid noise the windows assume; None follows the simulator (floor 1 px)")
    beta: float = param(3.0, help="window eps = beta sqrt(2) sigma (starid's reconstruction)")
    d_min_deg: float | None = param(
        None, help="stars closer than this to another are unused (doubles); None = 5.1 px, at most 1 deg", unit="deg")
    max_pair_deg: float = param(20.0, unit="deg",
                                help="largest separation of a stored pair (also capped at the field's diagonal)")
    max_stars: int = param(15, help="brightest detections that vote (starid's reconstruction)")
    max_window: int = param(
        10000, help="an image pair whose window holds more catalog pairs than this does not vote (a time bound)")
    min_support: int = param(2, help="other assignments a verified one must agree with (starid's reconstruction)")
    min_fraction: float = param(
        0.5, help="fraction of the other assignments a verified one must agree with (starid's reconstruction)")
    confirm_fraction: float = param(
        0.5, help="fraction of the guide stars the attitude predicts that must be seen; 0 = off (starid's extension)")
    min_extra: int = param(1, help="stars beyond 3 the attitude must see in all; 0 = off (starid's extension)")
    once_per_pair: bool = param(
        True, help="at most one vote per catalog star per image pair; off = LOST's (starid's reconstruction)")
    n_candidates: int = param(
        16, help="best catalog stars each image star keeps for the shortlist vote; 1 = paper (starid's reconstruction)")
    expected_votes: bool = param(
        True, help="rank catalog stars by votes minus the chance votes of their degree (starid's reconstruction)")
    round_voters: int = param(
        5, help="brightest stars voting in the first round; 0 = the paper's single round (starid's extension)")
    round_step: int = param(1, help="stars joining the vote per further round (starid's extension)")
    report_all: bool = param(
        True, help="report every star the confirming reprojection finds; off = voters only (starid's extension)")
    saturate_votes: bool | None = param(
        None, help="count chance votes as 1 - exp(-degree p) per pair; None = derived from the camera")
    vote_window_px: float | None = param(
        None, unit="px",
        help="half-width of the voting windows; None = derived: eps, narrowed on cameras with more chance votes")

    def __post_init__(self):
        check_pair_params(self)
        check_whole("max_stars", self.max_stars, 3, 255)
        check_whole("round_voters", self.round_voters, 0, 255)
        check_whole("round_step", self.round_step, 1, 255)
        check_flag("report_all", self.report_all)
        if self.saturate_votes is not None:
            check_flag("saturate_votes", self.saturate_votes)
        if self.vote_window_px is not None:
            check_number("vote_window_px", self.vote_window_px, lo=0)
            if not self.vote_window_px > 0:
                raise ConfigError(f"vote_window_px must be > 0, got {self.vote_window_px!r}")
        check_flag("once_per_pair", self.once_per_pair)
        check_flag("expected_votes", self.expected_votes)
        check_whole("n_candidates", self.n_candidates, 1, 1000)
        check_whole("min_support", self.min_support, 1)
        check_number("min_fraction", self.min_fraction, lo=0, hi=1)

    def tolerances(self, camera: Camera, database: PairDatabase) -> PairTol:
        return _bundles(self, camera, database.c_max, database.d_min_deg, _saturates(database),
                        _vote_window(database))[0]

    def derived(self, catalog: Catalog, camera: Camera) -> GeometricVoting:
        """``mag_limit``, ``d_min_deg``, ``saturate_votes`` and ``vote_window_px`` left None set for
        ``camera`` (:func:`derived_mag_limit` at the 1 px floor,
        :func:`~starid_algorithms.pyramid.algorithm.d_min_for`, :func:`derived_saturate`,
        :func:`derived_vote_window`)."""
        mag_limit = (derived_mag_limit(catalog, camera, self.max_pair_deg) if self.mag_limit is None
                     else self.mag_limit)
        return dataclasses.replace(
            self, mag_limit=mag_limit, d_min_deg=d_min_for(camera) if self.d_min_deg is None else self.d_min_deg,
            saturate_votes=derived_saturate(catalog, camera, mag_limit, self.max_pair_deg, self.sigma_px, self.beta)
            if self.saturate_votes is None else self.saturate_votes,
            vote_window_px=derived_vote_window(catalog, camera, mag_limit, self.max_pair_deg, self.sigma_px, self.beta)
            if self.vote_window_px is None else self.vote_window_px)

    def build(self, catalog: Catalog, camera: Camera) -> VotingDatabase:
        settled = self.derived(catalog, camera)
        mag_limit, d_min_deg = float(settled.mag_limit), float(settled.d_min_deg)
        db = build_pair_database(catalog, camera, mag_limit, d_min_deg, self.max_pair_deg, self.name,
                                 neighbour_lists=False)
        return VotingDatabase(**{f.name: getattr(db, f.name) for f in fields(db)}, mag_limit=mag_limit,
                              saturate_votes=bool(settled.saturate_votes),
                              vote_window_px=float(settled.vote_window_px))

    def rule(self, database_saturates: bool = False) -> VoteRule:
        """The kernel's :class:`VoteRule`; ``saturate_votes`` left None is the database's (what
        ``build`` derived), ``database_saturates``."""
        saturate = self.saturate_votes if self.saturate_votes is not None else database_saturates
        return VoteRule(once_per_pair=bool(self.once_per_pair), expected=bool(self.expected_votes),
                        n_candidates=int(self.n_candidates), round_voters=int(self.round_voters),
                        round_step=int(self.round_step),
                        min_support=int(self.min_support), min_fraction=float(self.min_fraction),
                        report_all=bool(self.report_all), saturate=bool(saturate))

    def _run(self, database: PairDatabase, observation: Observation):
        tol, sensor, rule, vtol, like = _kernel_bundles(self, observation.camera, database.c_max,
                                                        database.d_min_deg, _saturates(database),
                                                        _vote_window(database))
        return voting_kernel(observation.x_px, observation.y_px, observation.mag, tuple(database.kv), database.pairs,
                             database.degree, database.guide_unit, database.guide_hip, tol, sensor, rule, vtol, like)

    def identify(self, database: PairDatabase, observation: Observation) -> Identification:
        _, _, hip, attitude, found, work = self._run(database, observation)
        counters = dict(zip(WORK_COUNTERS, work.tolist(), strict=True))
        return Identification(hip, attitude if found else None, counters=counters)

    def explain(self, database: PairDatabase, observation: Observation) -> Explanation:
        """Every star of the deciding round labelled with the votes of its chosen catalog star (and
        the id if it survived verification); stars identified only by the confirming reprojection
        (``report_all``) labelled as such; segments join the identified voters whose pair angle
        matches their catalog stars' within eps (the verification votes)."""
        rows, votes, hip, _, _, _ = self._run(database, observation)
        xy = np.stack([observation.x_px, observation.y_px], axis=1)
        voters = np.flatnonzero(votes >= 0)
        extra = np.flatnonzero((rows >= 0) & (votes < 0))
        labels = tuple([f"{votes[s]} votes: HIP {hip[s]}" if hip[s] >= 0 else f"{votes[s]} votes: rejected"
                        for s in voters.tolist()] + [f"reprojection: HIP {hip[s]}" for s in extra.tolist()])
        found = np.flatnonzero((rows >= 0) & (votes >= 0))
        eps = self.tolerances(observation.camera, database).eps
        v = observation.unit_cam()
        unit = database.guide_unit.astype(np.float64)
        segments = [[xy[a], xy[b]] for i, a in enumerate(found.tolist()) for b in found[i + 1:].tolist()
                    if abs(np.linalg.norm(v[a] - v[b]) - np.linalg.norm(unit[rows[a]] - unit[rows[b]])) <= eps]
        caption = (f"{voters.size} stars voted; {found.size} survived the pairwise verification "
                   f"(segments: the {len(segments)} agreeing pairs); reprojection identified "
                   f"{extra.size} more." if found.size else
                   f"{voters.size} stars voted; no consistent set survived verification: nothing identified.")
        return Explanation(segments=np.asarray(segments, dtype=np.float64).reshape(-1, 2, 2),
                           points=np.concatenate([xy[voters], xy[extra]]), labels=labels, caption=caption)


def _vote_window(database: PairDatabase) -> float | None:
    """What ``build`` derived for ``vote_window_px`` (a plain pyramid database: None, the full eps)."""
    return getattr(database, "vote_window_px", None)


def _saturates(database: PairDatabase) -> bool:
    """What ``build`` derived for ``saturate_votes`` (a plain pyramid database: False)."""
    return bool(getattr(database, "saturate_votes", False))


@lru_cache(maxsize=64)
def _kernel_bundles(algorithm: GeometricVoting, camera: Camera, c_max: float, d_min_deg: float,
                    database_saturates: bool = False, database_vote_window_px: float | None = None) -> tuple:
    """:func:`_bundles` as ``voting_kernel`` takes them: plain tuples (numba types a named tuple
    argument in Python, ~0.8 µs each per call; ``voting_kernel`` rebuilds the named bundles), and
    the counters' dtype (:func:`~.kernels.tally_like`)."""
    tol, sensor, rule, vtol = _bundles(algorithm, camera, c_max, d_min_deg, database_saturates,
                                       database_vote_window_px)
    return tuple(tol), tuple(sensor), tuple(rule), tuple(vtol), tally_like(rule)


@lru_cache(maxsize=64)
def _bundles(algorithm: GeometricVoting, camera: Camera, c_max: float, d_min_deg: float,
             database_saturates: bool = False,
             database_vote_window_px: float | None = None) -> tuple[PairTol, Frame, VoteRule, PairTol]:
    """The kernel's bundles for one (algorithm, camera, database chord limit, double-star
    distance and derived ``saturate_votes``), built once rather
    than per image (immutable tuples: sharing them between calls and threads is safe).

    eps = ``beta`` sqrt(2) sigma with sigma = max(``sigma_px``, 1 px) / f_px: three standard
    deviations of the difference between an image chord and its catalog chord when each centroid
    has noise ``sigma_px`` per axis."""
    eps = window_eps(camera, algorithm.sigma_px, algorithm.beta)
    # as in pyramid: a detection with another one within eps of it can never be confirmed by the
    # reprojection (two detections near its prediction), so the image's isolation radius is at least eps
    tol = PairTol(eps=eps, d_min=max(rad_to_chord(math.radians(d_min_deg)), eps),
                  c_max=c_max, c_fov=rad_to_chord(camera.half_diagonal_rad), max_window=int(algorithm.max_window),
                  max_stars=int(algorithm.max_stars), max_triads=0, confirm_fraction=float(algorithm.confirm_fraction),
                  min_extra=int(algorithm.min_extra))
    # the voting windows (and the chance votes of the ranking): ``vote_window_px`` if pinned, else what
    # ``build`` derived (:func:`derived_vote_window`), never wider than eps; the same eps when they agree
    vote_px = algorithm.vote_window_px if algorithm.vote_window_px is not None else database_vote_window_px
    vtol = tol
    if vote_px is not None and float(vote_px) < eps * camera.f_px * (1.0 - 1e-9):
        vtol = tol._replace(eps=float(vote_px) / camera.f_px)
    return tol, camera_frame(camera), algorithm.rule(database_saturates), vtol

