"""``starid cameras``: the camera presets shipped with starid (``--camera NAME`` anywhere)."""

from __future__ import annotations

from ..cameras import describe, load_camera, preset_names


def cmd_cameras(args) -> int:
    if args.name:
        cam = load_camera(args.name)
        for key, value in cam.spec().items():
            print(f"{key:12s} {value}")
        d = describe(cam)
        print(f"{'fov_deg':12s} {d['fov_deg']}\n{'arcsec/px':12s} {d['arcsec_per_px']}")
        return 0
    rows = [describe(load_camera(n)) for n in preset_names()]
    head = ("name", "size_px", "fov_deg", "arcsec_per_px", "distortion", "source")
    widths = [max(len(h), *(len(str(r[h])) for r in rows)) for h in head[:-1]]
    print("  ".join(h.ljust(w) for h, w in zip(head[:-1], widths, strict=True)) + "  source")
    for r in rows:
        print("  ".join(str(r[h]).ljust(w) for h, w in zip(head[:-1], widths, strict=True)) + "  " + r["source"])
    return 0


def add_parsers(sub, formatter) -> None:
    p = sub.add_parser("cameras", formatter_class=formatter,
                       help="camera presets: size, field of view, pixel scale, source (use with --camera NAME)",
                       description="The camera presets shipped with starid. Any command with camera options takes "
                                   "--camera NAME or --camera FILE.toml (a [camera] table: width_px, height_px, "
                                   "pixel_um, focal_mm, optional cx_px, cy_px, distortion = [k1, k2, p1, p2, k3] "
                                   "(OpenCV), exposure_s, name, source).")
    p.add_argument("name", nargs="?", metavar="NAME|FILE", help="show one preset or camera file in full")
    p.set_defaults(func=cmd_cameras)
