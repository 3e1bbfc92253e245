"""``render`` (a simulated trial as an image file) and ``identify`` on image files.

``starid identify ALGO... IMAGE... --fov-deg F`` lands in :func:`identify_images` when the
last arguments are image files (FITS, TIFF, PNG, JPEG): each image is read
(:mod:`starid.imagefile`), its stars extracted (:func:`starid.extract.extract`), identified by
each algorithm at the field of view given and, when that fails, at scales up to
``--fov-search-pct`` per cent off, the focal length refined from the identified stars, and the
attitude solved (Wahba, SVD). docs/images.md describes the steps and the measured tolerance.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np
import pandas as pd

from ..attitude import solve_wahba
from ..camera import Camera
from ..catalog import load_csv, load_hipparcos
from ..errors import ConfigError, ObservationError
from ..experiment.executors import Limits, Outcome, call_per_item, memory_error
from ..harness import prepare, timed_identify
from ..imagefile import WRITE_SUFFIXES, is_image_file, read_image, write_image
from ..io import write_frames
from ..observation import Observation
from ..params import check_number
from ..render import RenderConfig, Renderer
from ..scoring import CRASHED, RAD_TO_ARCSEC
from ..simulate import SimConfig, Simulator
from .options import add_camera, add_world, camera_spec, check_out, make_camera, seed_type, world_settings

ATTITUDE_COLUMNS = ["image", "algorithm", "status", "ra_deg", "dec_deg", "roll_deg", "residual_arcsec", "n_identified"]
IMAGE_ID_COLUMNS = ["image", "algorithm", "label", "star", "x_px", "y_px", "mag", "flux", "hip"]
SOLVED, NOT_SOLVED, ERROR = "solved", "not solved", "error"
#: Relative focal-length step of the field-of-view search (measured: docs/images.md).
FOV_STEP = 0.005
#: An image is solved when at least this many stars are identified.
MIN_IDENTIFIED = 3


# --------------------------------------------------------------------------------------- attitude

def _r1(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0, 0], [0, c, s], [0, -s, c]])


def _r3(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, s, 0], [-s, c, 0], [0, 0, 1.0]])


def ra_dec_roll_deg(attitude: np.ndarray) -> tuple[float, float, float]:
    """Boresight right ascension and declination and the roll of an attitude (ICRS -> camera).

    The 3-1-3 convention ``A = R3(roll) R1(90 deg - dec) R3(90 deg + ra)`` (passive rotations):
    at roll 0 celestial north points to image +y (down) and east to image +x (right); roll is the
    angle of the last rotation about the boresight, in [0, 360).
    :func:`attitude_from_ra_dec_roll` is its inverse.
    """
    b = attitude[2]                                   # the boresight in ICRS
    dec = math.asin(max(-1.0, min(1.0, b[2])))
    ra = math.atan2(b[1], b[0]) % (2 * math.pi)
    m = attitude @ (_r1(math.pi / 2 - dec) @ _r3(math.pi / 2 + ra)).T
    roll = math.atan2(m[0, 1], m[0, 0]) % (2 * math.pi)
    return math.degrees(ra), math.degrees(dec), math.degrees(roll)


def attitude_from_ra_dec_roll(ra_deg: float, dec_deg: float, roll_deg: float) -> np.ndarray:
    ra, dec, roll = (math.radians(v) for v in (ra_deg, dec_deg, roll_deg))
    return _r3(roll) @ _r1(math.pi / 2 - dec) @ _r3(math.pi / 2 + ra)


def _solve(hip, obs: Observation, catalog):
    """``(attitude, residual_arcsec)`` from the identified stars, ``(None, nan)`` with fewer than 2."""
    ok = np.flatnonzero(hip != -1)
    if ok.size < 2:
        return None, float("nan")
    b = obs.unit_cam()[ok]
    r = catalog.unit_icrs[catalog.index_of(hip[ok])]
    attitude = solve_wahba(b, r)
    cosang = np.clip(np.sum(b * (r @ attitude.T), axis=1), -1.0, 1.0)
    resid = np.arccos(cosang)
    return attitude, float(np.sqrt(np.mean(resid ** 2)) * RAD_TO_ARCSEC)


def _refine_f_px(hip, x_px, y_px, camera: Camera, catalog, iterations: int = 4) -> float:
    """The focal length (px) that best fits the identified stars (alternating with Wahba).

    With lens distortion the fit is on the undistorted positions (each iteration undistorts with
    the current focal length: the distortion acts on normalized coordinates)."""
    ok = np.flatnonzero(hip != -1)
    f = camera.f_px
    r = catalog.unit_icrs[catalog.index_of(hip[ok])]
    dx, dy = x_px[ok] - camera.cx_px, y_px[ok] - camera.cy_px
    if ok.size < 3 or np.max(np.hypot(dx, dy)) < 5.0:
        return f
    for _ in range(iterations):
        cam = _with_f(camera, f)
        attitude = solve_wahba(cam.backproject(x_px[ok], y_px[ok]), r)
        if cam.distorted:
            ux, uy = cam.undistort(x_px[ok], y_px[ok])
            dx, dy = ux - cam.pinhole_frame.cx_px, uy - cam.pinhole_frame.cy_px
        c = r @ attitude.T
        u, v = c[:, 0] / c[:, 2], c[:, 1] / c[:, 2]
        f = float((dx * u + dy * v).sum() / (u * u + v * v).sum())
    return f


def _with_f(camera: Camera, f_px: float) -> Camera:
    """``camera`` with focal length ``f_px``: sensor, pixel, principal point, distortion, name and
    source kept (the distortion is on normalized coordinates, so it scales with the focal length)."""
    return camera.replace(focal_mm=f_px * camera.pixel_um / 1000.0)


def _fov_scales(search_pct: float) -> list[float]:
    k = int(math.floor(search_pct / 100.0 / FOV_STEP + 1e-9))
    scales = [1.0]
    for i in range(1, k + 1):
        scales += [1.0 + i * FOV_STEP, 1.0 - i * FOV_STEP]
    return scales


def f_px_of_fov(width_px: int, fov_deg: float) -> float:
    """The focal length (px) giving ``fov_deg`` across ``width_px`` (pinhole, principal point centred)."""
    return (width_px / 2.0) / math.tan(math.radians(fov_deg) / 2.0)


def parse_fov_range(text: str) -> tuple[float, float]:
    """``--fov-range MIN:MAX`` (degrees across the image width): ``(min, max)``, checked."""
    parts = str(text).split(":")
    try:
        lo, hi = (float(v) for v in parts)
    except ValueError:
        raise ConfigError(f"--fov-range must be MIN:MAX in degrees (e.g. 8:12), got {text!r}") from None
    if not (math.isfinite(lo) and math.isfinite(hi)) or lo <= 0 or hi >= 180:
        raise ConfigError(f"--fov-range {text}: both ends must be above 0 and below 180 deg")
    if lo >= hi:
        raise ConfigError(f"--fov-range {text}: MIN must be below MAX")
    return lo, hi


def range_scales(camera: Camera, fov_range_deg: tuple[float, float]) -> list[float]:
    """Focal-length scales (of ``camera.f_px``) covering ``fov_range_deg`` across the width, steps of
    :data:`FOV_STEP` (relative): from the camera's own focal length when it is in the range (else
    the range's geometric middle), alternately outwards."""
    f_lo = f_px_of_fov(camera.width_px, fov_range_deg[1]) / camera.f_px
    f_hi = f_px_of_fov(camera.width_px, fov_range_deg[0]) / camera.f_px
    start = 1.0 if f_lo <= 1.0 <= f_hi else math.sqrt(f_lo * f_hi)
    scales, i = [start], 1
    step = 1.0 + FOV_STEP
    while True:
        up, down = start * step ** i, start / step ** i
        if up > f_hi and down < f_lo:
            break
        scales += [s for s in (up, down) if f_lo <= s <= f_hi]
        i += 1
    return scales


#: A database serves focal lengths within this factor either way of the one it was built for
#: (the +-5 % default search uses one); a wider ``--fov-range`` builds one per such band.
BAND = 1.12


def band_of(scale: float) -> int:
    """The database band of a focal-length scale (0 holds every scale within +-5.8 %)."""
    return int(round(math.log(scale) / math.log(BAND)))


def solve_image(prepared, obs: Observation, catalog, search_pct: float = 5.0,
                fov_range_deg: tuple[float, float] | None = None, prepared_for=None, on_call=None):
    """Identify ``obs`` at its camera and, failing that, over focal-length scales within
    ``search_pct`` per cent (or covering ``fov_range_deg``, degrees across the width); refine the
    focal length and identify again.

    With ``fov_range_deg`` the search stops at the first scale where at least
    :data:`MIN_IDENTIFIED` stars fit within 3 px rms, and ``prepared_for(band)`` gives the prepared
    algorithm of each database band (:func:`band_of`; ``prepared`` serves band 0). The searched
    cameras keep everything of ``obs.camera`` but the focal length (distortion included). ``on_call()`` is
    called before each ``identify`` (the supervising process holds each call to ``--time-limit``).

    Returns ``(hip, camera, attitude, residual_arcsec, error)``.
    """
    best = None
    scales = _fov_scales(search_pct) if fov_range_deg is None else range_scales(obs.camera, fov_range_deg)
    for s in scales:
        cam = _with_f(obs.camera, obs.camera.f_px * s)
        o = Observation(obs.x_px, obs.y_px, obs.mag, cam)
        band = band_of(s) if fov_range_deg is not None else 0
        p = prepared if band == 0 or prepared_for is None else prepared_for(band)
        if on_call is not None:
            on_call()
        hip, _, error = timed_identify(p, o, catalog.hip)
        if error:
            return hip, obs.camera, None, float("nan"), error
        n = int((hip != -1).sum())
        if n >= MIN_IDENTIFIED:
            _, resid = _solve(hip, o, catalog)
            if best is None or (n, -resid) > (best[0], -best[1]):
                best = (n, resid, hip, cam, p)
            fits = resid < 3.0 * cam.pixel_rad * RAD_TO_ARCSEC
            if fits and (s == 1.0 or fov_range_deg is not None):
                break                                  # the field of view fits: no (further) search
    if best is None:
        return np.full(len(obs), -1, dtype=np.int64), obs.camera, None, float("nan"), ""
    _, _, hip, cam, p = best
    # a range search stops at the first scale that fits, up to ~1 % off, often with fewer stars:
    # refine and identify again while that identifies more (the +-5 % search: once, as before)
    for _ in range(1 if fov_range_deg is None else 3):
        cam = _with_f(cam, _refine_f_px(hip, obs.x_px, obs.y_px, cam, catalog))
        o = Observation(obs.x_px, obs.y_px, obs.mag, cam)
        if on_call is not None:
            on_call()
        hip2, _, error = timed_identify(p, o, catalog.hip)
        more = not error and int((hip2 != -1).sum()) > int((hip != -1).sum())
        if not error and int((hip2 != -1).sum()) >= int((hip != -1).sum()):
            hip = hip2
        if not more:
            break
    attitude, resid = _solve(hip, o, catalog)
    return hip, cam, attitude, resid, ""


def band_preparer(variant, catalog, camera: Camera, warmup=None, on_phase=None):
    """``prepared_for(band)`` of :func:`solve_image`: the algorithm prepared for ``camera`` with its
    focal length scaled by ``BAND ** band`` (built on first use, then kept; ``on_phase`` as
    :func:`~starid.harness.prepare`'s)."""
    cache = {}

    def prepared_for(band: int):
        if band not in cache:
            cam = _with_f(camera, camera.f_px * BAND ** band)
            cache[band] = prepare(variant.make(), catalog, cam, warmup, variant.label, on_phase)
        return cache[band]

    return prepared_for


# ----------------------------------------------------------------------------------- magnitudes

def auto_zero_point(flux: np.ndarray, camera: Camera, catalog, guide_mag: float = 6.0) -> float:
    """A magnitude zero point for an uncalibrated image, from star counts.

    The field holds on average ``N = (stars with V <= guide_mag) x (field solid angle) / 4 pi``
    guide stars; the ``min(N, n)``-th brightest detection is given magnitude ``guide_mag``.
    """
    if flux.size == 0:
        return 0.0
    half_w = math.atan(camera.width_px / 2.0 / camera.f_px)
    half_h = math.atan(camera.height_px / 2.0 / camera.f_px)
    solid_sr = 4.0 * math.asin(math.sin(half_w) * math.sin(half_h))   # a rectangular pyramid
    n_guide = int(np.count_nonzero(catalog.v_mag <= guide_mag)) * solid_sr / (4.0 * math.pi)
    k = int(min(max(round(n_guide), 1), flux.size)) - 1
    return guide_mag + 2.5 * math.log10(np.sort(flux)[::-1][k])


# ------------------------------------------------------------------------------------ annotation

def annotate(path: Path, image: np.ndarray, x_px, y_px, hip, title: str) -> None:
    """A PNG of ``image`` (asinh stretch) with every detection circled, identified ones in
    colour with their HIP number."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Circle

    from ..io import atomic_write_bytes

    h, w = image.shape
    level = float(np.median(image))
    rms = 1.4826 * float(np.median(np.abs(image - level))) or 1.0
    shown = np.arcsinh(np.clip(image - level, 0, None) / (4.0 * rms))
    low, top = math.asinh(0.5), math.asinh(25.0)   # 2 rms -> black, 100 rms -> white
    scale = 8.0 / max(w, h)
    fig = plt.figure(figsize=(w * scale, h * scale + 0.4), dpi=max(w, h) / 8.0)
    ax = fig.add_axes([0, 0, 1, h * scale / (h * scale + 0.4)])
    ax.imshow(shown, cmap="gray", vmin=low, vmax=top, origin="upper", extent=(0, w, h, 0), interpolation="nearest")
    radius = max(w, h) / 80.0
    for x, y, h_id in zip(x_px, y_px, hip, strict=True):
        ident = h_id != -1
        ax.add_patch(Circle((x, y), radius * (1.3 if ident else 1.0), fill=False, lw=1.2 if ident else 0.6,
                            ec="#ffcc00" if ident else "#4aa3ff"))
        if ident:
            left = x > 0.88 * w                       # keep the label on the image
            ax.text(x - radius * 1.5 if left else x + radius * 1.5, y - radius * 1.2, f"HIP {int(h_id)}",
                    color="#ffcc00", fontsize=7, ha="right" if left else "left")
    ax.set_xlim(0, w)
    ax.set_ylim(h, 0)
    ax.axis("off")
    fig.text(0.01, 1.0 - 0.2 / (h * scale + 0.4), title, fontsize=8, va="center")
    buf = __import__("io").BytesIO()
    fig.savefig(buf, format="png", facecolor="white")
    plt.close(fig)
    atomic_write_bytes(path, buf.getvalue())


# -------------------------------------------------------------------------------------- identify

def _image_camera(args, width_px: int, height_px: int) -> Camera:
    """The camera of one image: its own size, the field of view across its width (or --focal-mm);
    with ``--camera`` that calibration (its size must be the image's), the options overriding it."""
    if getattr(args, "camera", None) is not None:
        cam = make_camera(camera_spec(args))
        if (cam.width_px, cam.height_px) != (width_px, height_px):
            raise ConfigError(f"--camera {args.camera} is {cam.width_px}x{cam.height_px} px but the image is "
                              f"{width_px}x{height_px} px")
        return cam
    pixel_um = args.pixel_um if getattr(args, "pixel_um", None) is not None else 12.0
    check_number("--pixel-um", pixel_um, lo=0, lo_open=True)
    if args.fov_deg is not None and args.focal_mm is not None:
        raise ConfigError("give either --fov-deg or --focal-mm, not both")
    if args.fov_deg is not None:
        check_number("--fov-deg", args.fov_deg, lo=0, hi=180, lo_open=True, hi_open=True)
        f_px = (width_px / 2.0) / math.tan(math.radians(args.fov_deg) / 2.0)
    elif args.focal_mm is not None:
        check_number("--focal-mm", args.focal_mm, lo=0, lo_open=True)
        f_px = args.focal_mm * 1000.0 / pixel_um
    else:            # no field of view given: the middle of the search range (--fov-range, default the presets')
        lo, hi = search_range(args)
        f_px = math.sqrt(f_px_of_fov(width_px, lo) * f_px_of_fov(width_px, hi))
    return Camera(width_px, height_px, pixel_um, f_px * pixel_um / 1000.0)


def preset_fov_range() -> tuple[float, float]:
    """The default ``--fov-range`` without a field of view: 0.9 x the narrowest preset's field
    across the width to 1.1 x the widest's (9-55 deg with the shipped presets)."""
    from ..cameras import camera_from_spec, preset_names

    fovs = [camera_from_spec({"preset": n}).fov_x_deg for n in preset_names()]
    return round(0.9 * min(fovs), 3), round(1.1 * max(fovs), 3)


def search_range(args) -> tuple[float, float] | None:
    """The ``--fov-range`` to search (degrees), ``None`` for the +-``--fov-search-pct`` search around
    the given field of view; without any field of view, focal length or camera, the presets' range."""
    text = getattr(args, "fov_range", None)
    if text is not None:
        if getattr(args, "fov_search_pct", None) is not None:
            raise ConfigError("give either --fov-range or --fov-search-pct, not both")
        return parse_fov_range(text)
    if all(getattr(args, k, None) is None for k in ("fov_deg", "focal_mm", "camera")):
        return preset_fov_range()
    return None


def _split_items(items: list[str]) -> tuple[list[str], list[Path]]:
    k = len(items)
    while k > 0 and is_image_file(items[k - 1]):
        k -= 1
    algorithms, images = items[:k], [Path(p) for p in items[k:]]
    if not algorithms:
        raise ObservationError("identify needs at least one algorithm before the image files")
    bad = [a for a in algorithms if is_image_file(a) or Path(a).suffix.lower() == ".csv"]
    if bad:
        raise ObservationError(f"{bad[0]}: give the algorithms first, then the image files (no CSV among images)")
    return algorithms, images


def _solve_images(variant, catalog, camera: Camera, observations, search_pct, fov_range, control, start):
    """In the supervised process: prepare ``variant`` for ``camera`` and solve images ``start..``, each sent
    with ``control.emit((k, solve_image's result))``."""
    def on_phase(phase: str) -> None:
        control.phase("the warm-up identify" if phase == "warmup" else "derived/build", build=True)

    prepared = prepare(variant.make(), catalog, camera, None, variant.label, on_phase)
    bands = band_preparer(variant, catalog, camera, None, on_phase)
    for k in range(start, len(observations)):
        control.phase("identify")
        control.emit((k, solve_image(prepared, observations[k], catalog, search_pct, fov_range, bands,
                                     on_call=lambda: control.phase("identify"))))


def identify_images(args) -> int:
    """``starid identify ALGO... IMAGE... --fov-deg F [--out DIR]`` (see the module)."""
    from .experiments import variants

    algorithms, paths = _split_items(list(args.items))
    out = args.out if args.out is not None else Path(".")
    check_out(out)
    limits = Limits.from_args(args)
    if getattr(args, "resolution", None) is not None:
        raise ConfigError("--resolution does not apply to image files: each image's own size is used")
    fov_range = search_range(args)
    search_pct = getattr(args, "fov_search_pct", None)
    search_pct = 5.0 if search_pct is None else search_pct
    check_number("--fov-search-pct", search_pct, lo=0, hi=30)
    psf = getattr(args, "psf_sigma_px", 2.0)
    threshold = getattr(args, "threshold_sigma", 3.0)
    zero_point = getattr(args, "zero_point_mag", None)
    from ..extract import extract

    images = []
    for path in paths:                       # read and extract everything first: bad input writes nothing
        data = read_image(path)
        camera = _image_camera(args, data.shape[1], data.shape[0])
        x, y, mag, flux = extract(data, psf_sigma_px=psf, threshold_sigma=threshold)
        images.append((path, data, camera, x, y, flux))
    catalog = load_csv(args.catalog) if args.catalog else load_hipparcos()
    chosen = variants(algorithms, args.set)
    if fov_range is not None:
        print(f"searching fields of view {fov_range[0]:g}-{fov_range[1]:g} deg across the width")
    observations = []
    for _path, _data, camera, x, y, flux in images:
        zp = zero_point if zero_point is not None else auto_zero_point(flux, camera, catalog)
        mag = zp - 2.5 * np.log10(flux) if flux.size else np.zeros(0)
        observations.append(Observation(x, y, mag, camera))
    # every plugin call in a supervised process per algorithm (the engine's limits): one that overruns or
    # dies is that image's (preparing: every image's) timeout / crashed row, the other algorithms' intact
    solved = []
    for v in chosen:
        def compute(control, start, v=v):
            return _solve_images(v, catalog, images[0][2], observations, search_pct, fov_range, control, start)

        solved.append(call_per_item(compute, len(images), limits))
    att_rows, id_frames, best_ids = [], [], {}
    for k, (path, _data, camera, x, y, flux) in enumerate(images):
        obs = observations[k]
        mag = obs.mag
        for v, items in zip(chosen, solved, strict=True):
            item = items[k]
            status = ""
            if isinstance(item, Outcome):
                hip, cam, attitude, resid, error = np.full(len(obs), -1, dtype=np.int64), camera, None, math.nan, \
                    item.error
                status = item.status
            else:
                hip, cam, attitude, resid, error = item
                memory = memory_error(error, limits.memory_limit_gb)
                if memory:
                    status, error = CRASHED, memory
            n_id = int((hip != -1).sum())
            row = {"image": str(path), "algorithm": v.label, "status": status or (ERROR if error else NOT_SOLVED),
                   "ra_deg": math.nan, "dec_deg": math.nan, "roll_deg": math.nan, "residual_arcsec": math.nan,
                   "n_identified": n_id}
            if not error and attitude is not None and n_id >= MIN_IDENTIFIED:
                ra, dec, roll = ra_dec_roll_deg(attitude)
                row.update(status=SOLVED, ra_deg=ra, dec_deg=dec, roll_deg=roll, residual_arcsec=resid)
            att_rows.append(row)
            note = f"fov {cam.fov_x_deg:.4g} deg" if row["status"] == SOLVED else (error or "not solved")
            print(f"{path}: {v.label}: {row['status']}, {n_id} of {len(obs)} stars identified"
                  + (f", ra {row['ra_deg']:.4f} dec {row['dec_deg']:.4f} roll {row['roll_deg']:.2f} deg, "
                     f"residual {resid:.1f} arcsec, {note}" if row["status"] == SOLVED else f" ({note})"))
            id_frames.append(pd.DataFrame({"image": str(path), "algorithm": v.name, "label": v.label,
                                           "star": np.arange(len(obs)), "x_px": x, "y_px": y, "mag": mag,
                                           "flux": flux, "hip": hip}))
            prev = best_ids.get(path)
            if prev is None or n_id > prev[0]:
                best_ids[path] = (n_id, hip, v.label)
    frames = {"attitudes.csv": pd.DataFrame(att_rows, columns=ATTITUDE_COLUMNS),
              "identifications.csv": pd.concat(id_frames, ignore_index=True)[IMAGE_ID_COLUMNS]}
    write_frames(out, frames)
    stems = [p.stem for p in paths]
    for (path, data, _camera, x, y, _flux), stem in zip(images, stems, strict=True):
        n_id, hip, label = best_ids[path]
        name = stem if stems.count(stem) == 1 else f"{stem}{path.suffix.replace('.', '_')}"
        statuses = ", ".join(f"{r['algorithm']}: {r['status']}" for r in att_rows if r["image"] == str(path))
        annotate(out / f"{name}.annotated.png", data, x, y, hip,
                 f"{path.name}: {len(x)} detections, {n_id} identified by {label} ({statuses})")
    print(f"wrote attitudes.csv, identifications.csv and {len(images)} annotated PNG(s) to {out}")
    return 0


def add_identify_options(p: argparse.ArgumentParser) -> None:
    """Options of ``starid identify`` that apply to image files only."""
    g = p.add_argument_group("image files (FITS, TIFF, PNG, JPEG; needs starid-bench[images])")
    g.add_argument("--fov-search-pct", type=float, default=None,
                   help="when the given field of view does not fit, search focal lengths up to this many per cent "
                        "off (then refined from the stars; default 5)")
    p.add_argument_group("field-of-view search (image files and centroid files)").add_argument(
        "--fov-range", metavar="MIN:MAX",
        help="search fields of view from MIN to MAX deg across the image width (0.5 %% steps, one database per "
             "12 %% band; docs/cameras.md gives the cost). Images: default +-5 %% around --fov-deg/--focal-mm/"
             "--camera, or 0.9x-1.1x the presets' (9-55 deg) without them; centroid files: no search by default")
    g.add_argument("--psf-sigma-px", type=float, default=2.0, help="star image sigma in px (detection filter)")
    g.add_argument("--threshold-sigma", type=float, default=3.0, help="detection threshold in background rms")
    g.add_argument("--zero-point-mag", type=float, default=None,
                   help="magnitude of 1 ADU of flux (default: from star counts, the N-th brightest detection "
                        "at V 6 where N is the mean number of V <= 6 stars in such a field)")


# ---------------------------------------------------------------------------------------- render

def _size_type(text: str) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be WIDTHxHEIGHT in px, e.g. 1024x768, got {text!r}") from None
    if not (8 <= w <= 20000 and 8 <= h <= 20000):
        raise argparse.ArgumentTypeError(f"width and height must be from 8 to 20000 px, got {text!r}")
    return w, h


def render_camera(args) -> Camera:
    """The camera options of ``render``: Table 4 by default; ``--size WxH`` with the field of view
    across the width (``--fov-deg``) or the focal length."""
    if args.size is not None and getattr(args, "camera", None) is not None:
        if args.resolution is not None:
            raise ConfigError("give either --size or --resolution, not both")
        args.resolution = args.size
        args.size = None
    spec = camera_spec(args)
    if args.size is None:
        return make_camera(spec)
    if args.resolution is not None:
        raise ConfigError("give either --size or --resolution, not both")
    w, h = args.size
    pixel_um = spec.get("pixel_um", 12.0)
    if "fov_deg" in spec:
        check_number("--fov-deg", spec["fov_deg"], lo=0, hi=180, lo_open=True, hi_open=True)
        f_px = (w / 2.0) / math.tan(math.radians(spec["fov_deg"]) / 2.0)
        return Camera(w, h, pixel_um, f_px * pixel_um / 1000.0)
    return Camera(w, h, pixel_um, spec.get("focal_mm", Camera().focal_mm))


def cmd_render(args) -> int:
    from ..experiment.spec import sim_settings

    out: Path = args.out
    if out.suffix.lower() not in WRITE_SUFFIXES:
        raise ConfigError(f"--out {out}: the suffix must be one of {', '.join(WRITE_SUFFIXES)}")
    check_out(out.parent if str(out.parent) else Path("."))
    config = SimConfig(**sim_settings(world_settings(args), {}))
    catalog = load_csv(args.catalog) if args.catalog else load_hipparcos()
    camera = render_camera(args)
    fields = {k: getattr(args, k) for k in ("psf_sigma_px", "zero_point_mag", "exposure_s", "sky_e_per_px",
                                            "read_noise_e", "gain_e_per_adu", "bias_adu", "full_well_e",
                                            "hot_pixels")}
    render_config = RenderConfig(**fields)
    renderer = Renderer(Simulator(catalog, camera, config, seed=args.seed), render_config)
    rendered = renderer.render(args.trial)
    write_image(out, rendered.image, bits=args.bits)
    on = camera.in_image(rendered.x_px, rendered.y_px)
    ra, dec, roll = ra_dec_roll_deg(rendered.attitude)
    print(f"wrote {out}: trial {args.trial} (seed {args.seed}), {camera.width_px}x{camera.height_px} px, "
          f"fov {camera.fov_x_deg:.4g} deg, {int(on.sum())} stars (V <= {rendered.v_mag[on].max():.2f}) on the "
          f"sensor, {int((on & (rendered.v_mag <= 6.0)).sum())} with V <= 6; boresight ra {ra:.4f} dec {dec:.4f} "
          f"roll {roll:.2f} deg")
    if args.truth is not None:
        frame = pd.DataFrame({"x_px": rendered.x_px[on], "y_px": rendered.y_px[on], "v_mag": rendered.v_mag[on],
                              "hip": rendered.hip[on]})
        write_frames(args.truth.parent if str(args.truth.parent) else Path("."), {args.truth.name: frame})
        print(f"wrote the true stars to {args.truth}")
    return 0


def add_parsers(sub, formatter) -> None:
    if "identify" in sub.choices:
        add_identify_options(sub.choices["identify"])
    d = RenderConfig()
    p = sub.add_parser("render", help="render a simulated trial to an image file (TIFF, FITS, PNG)",
                       formatter_class=formatter,
                       epilog="examples:\n  starid render --trial 3 --out trial3.tiff\n"
                              "  starid render --trial 3 --size 1024x768 --fov-deg 10 --out wide.fits\n"
                              "  starid identify ptp trial3.tiff --fov-deg 10 --out ids/",
                       description="Render trial K of the simulator (the attitude of (seed, K), every star of the "
                                   "sky) as a star tracker would record it: Gaussian PSF, sky, shot and read noise, "
                                   "saturation. Same seed and trial, same image.")
    p.add_argument("--trial", type=int, required=True, help="trial index")
    p.add_argument("--seed", type=seed_type, default=0, help="simulator seed")
    p.add_argument("--out", type=Path, required=True, metavar="FILE", help="FILE.tiff, FILE.fits or FILE.png")
    p.add_argument("--truth", type=Path, metavar="FILE.csv", help="also write the true stars on the sensor")
    p.add_argument("--bits", type=int, choices=(8, 16), default=16,
                   help="8 stretches the image to 8 bits (TIFF, PNG); FITS is always 16")
    add_world(p, exposure=False)   # its --exposure-s (sensor group) is also the smear's
    add_camera(p)
    p.add_argument_group("camera").add_argument("--size", type=_size_type, metavar="WxH",
                                                help="image size in px (e.g. 1024x768); --fov-deg is across the width")
    g = p.add_argument_group("sensor (docs/images.md)")
    g.add_argument("--psf-sigma-px", type=float, default=d.psf_sigma_px, help="Gaussian PSF sigma in px")
    g.add_argument("--zero-point-mag", type=float, default=d.zero_point_mag, help="magnitude giving 1 e-/s")
    g.add_argument("--exposure-s", type=float, default=d.exposure_s, help="exposure in s")
    g.add_argument("--sky-e-per-px", type=float, default=d.sky_e_per_px, help="sky background in e- per px")
    g.add_argument("--read-noise-e", type=float, default=d.read_noise_e, help="read noise sigma in e-")
    g.add_argument("--gain-e-per-adu", type=float, default=d.gain_e_per_adu, help="e- per ADU")
    g.add_argument("--bias-adu", type=float, default=d.bias_adu, help="offset in ADU")
    g.add_argument("--full-well-e", type=float, default=d.full_well_e, help="saturation in e-")
    g.add_argument("--hot-pixels", type=int, default=d.hot_pixels, help="hot pixels per image")
    p.set_defaults(func=cmd_render)


__all__ = ["ATTITUDE_COLUMNS", "IMAGE_ID_COLUMNS", "add_parsers", "attitude_from_ra_dec_roll", "identify_images",
           "ra_dec_roll_deg", "solve_image"]
