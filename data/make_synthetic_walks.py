"""Write synthetic walking clips in AMASS's ``*_poses.npz`` format from the gait simulator.

    python data/make_synthetic_walks.py --out data/cache/synthwalk
    python data/prepare_amass.py data/cache/synthwalk data/cache/synthwalk_walking.npz \
        --val SynthWalkVal --test SynthWalkTest

Layout: OUT/SynthWalk{Train,Val,Test}/<subject>/<clip>_walk_poses.npz and OUT/manifest.json.
Test clips come from held-out subjects AND a held-out speed band (default 1.0–1.2 m/s);
validation clips from held-out subjects at training speeds. See gaitnet/sim/amass_clips.py.
"""

from __future__ import annotations

import argparse
import sys
import time

from tqdm import tqdm

from gaitnet.errors import USER_ERRORS, user_error_message
from gaitnet.sim.amass_clips import SyntheticWalksConfig, make_synthetic_walks
from gaitnet.training.scripts import ScriptParser


def _band(text: str) -> tuple[float, float]:
    lo, _, hi = text.partition("-")
    try:
        return float(lo), float(hi)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"expected LO-HI (e.g. 1.0-1.2), got {text!r}") from exc


def main(argv: list[str] | None = None) -> int:
    d = SyntheticWalksConfig()
    parser = ScriptParser(prog="data/make_synthetic_walks.py", description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True, help="root folder to write (AMASS-like layout)")
    parser.add_argument("--seed", type=int, default=d.seed, help="random seed, 0 ≤ N < 2**32")
    parser.add_argument("--overwrite", action="store_true", help="replace an existing --out")
    parser.add_argument(
        "--n-subjects",
        type=int,
        nargs=3,
        metavar=("TRAIN", "VAL", "TEST"),
        default=[d.train_subjects, d.val_subjects, d.test_subjects],
        help="subjects per split",
    )
    parser.add_argument("--walks-per-subject", type=int, default=d.walks_per_subject)
    parser.add_argument(
        "--train-speeds",
        type=_band,
        nargs="+",
        default=list(d.train_speed_bands),
        help="speed bands of training and validation clips, e.g. 0.6-1.0 1.2-1.7",
    )
    parser.add_argument(
        "--test-speeds",
        type=_band,
        nargs="+",
        default=list(d.test_speed_bands),
        help="held-out speed band(s) of test clips",
    )
    parser.add_argument(
        "--rates", type=float, nargs="+", default=list(d.mocap_rates_hz), help="mocap rates [Hz]"
    )
    try:
        args = parser.parse_args(argv)
        cfg = SyntheticWalksConfig(
            seed=args.seed,
            train_subjects=args.n_subjects[0],
            val_subjects=args.n_subjects[1],
            test_subjects=args.n_subjects[2],
            walks_per_subject=args.walks_per_subject,
            train_speed_bands=tuple(args.train_speeds),
            test_speed_bands=tuple(args.test_speeds),
            mocap_rates_hz=tuple(args.rates),
        )
    except (ValueError, *USER_ERRORS) as exc:  # the config's range checks raise ValueError
        print(f"error: {user_error_message(exc)}", file=sys.stderr)
        return 1
    t0 = time.perf_counter()
    try:
        report = make_synthetic_walks(
            args.out,
            cfg,
            overwrite=args.overwrite,
            progress=lambda jobs, total: tqdm(jobs, total=total, desc="subjects", unit="subject"),
        )
    except USER_ERRORS as exc:
        print(f"error: {user_error_message(exc)}", file=sys.stderr)
        return 1
    print(
        f"wrote {len(report.clips)} clips under {report.root} in {time.perf_counter() - t0:.0f} s"
    )
    for split in ("train", "val", "test"):
        n, minutes = report.count(split)
        print(f"  {split:5s} {n:4d} clips {minutes:6.1f} min")
    return 0


if __name__ == "__main__":
    sys.exit(main())
