"""Write synthetic walking clips in AMASS's ``*_poses.npz`` format from the gait simulator.

    python data/make_synthetic_walks.py --out data/cache/synthwalk_mix \
        --config configs/predictor/data/synthwalk_mix.yaml        # the committed model's mix
    python data/make_synthetic_walks.py --out data/cache/synthwalk   # whole walks only
    python data/prepare_amass.py data/cache/synthwalk data/cache/synthwalk_walking.npz \
        --val SynthWalkVal --test SynthWalkTest

Layout: OUT/SynthWalk{Train,Val,Test}/<subject>/<clip>_walk_poses.npz and OUT/manifest.json.
Test clips come from held-out subjects AND a held-out speed band (default 1.0–1.2 m/s);
validation clips from held-out subjects at training speeds. ``--config`` reads the keys of
``gaitnet.sim.amass_clips.SyntheticWalksConfig`` from a YAML file (the clip mix: standing,
pauses, sharp turns, speed changes, asymmetric walks; gaitnet/sim/amass_mix.py); options given
on the command line override it. See gaitnet/sim/amass_clips.py and docs/predictor.md.
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace

from tqdm import tqdm

from gaitnet.config import load_config
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
    parser = ScriptParser(prog="data/make_synthetic_walks.py", description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True, help="root folder to write (AMASS-like layout)")
    parser.add_argument("--config", help="YAML of SyntheticWalksConfig keys (the clip mix)")
    parser.add_argument("--seed", type=int, help="random seed, 0 ≤ N < 2**32")
    parser.add_argument("--overwrite", action="store_true", help="replace an existing --out")
    parser.add_argument(
        "--n-subjects",
        type=int,
        nargs=3,
        metavar=("TRAIN", "VAL", "TEST"),
        help="subjects per split",
    )
    parser.add_argument("--walks-per-subject", type=int, help="clips per subject")
    parser.add_argument(
        "--train-speeds",
        type=_band,
        nargs="+",
        help="speed bands of training and validation clips, e.g. 0.6-1.0 1.2-1.7",
    )
    parser.add_argument(
        "--test-speeds",
        type=_band,
        nargs="+",
        help="held-out speed band(s) of test clips",
    )
    parser.add_argument("--rates", type=float, nargs="+", help="mocap rates [Hz]")
    try:
        args = parser.parse_args(argv)
        cfg = load_config(SyntheticWalksConfig, args.config)
        given = {
            "seed": args.seed,
            "walks_per_subject": args.walks_per_subject,
            "train_speed_bands": None if args.train_speeds is None else tuple(args.train_speeds),
            "test_speed_bands": None if args.test_speeds is None else tuple(args.test_speeds),
            "mocap_rates_hz": None if args.rates is None else tuple(args.rates),
        }
        if args.n_subjects is not None:
            given.update(zip(("train_subjects", "val_subjects", "test_subjects"),
                             args.n_subjects, strict=True))  # fmt: skip
        cfg = replace(cfg, **{k: v for k, v in given.items() if v is not None})
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
        kinds = {}
        for c in report.clips:
            if c.split == split:
                kinds[c.kind] = kinds.get(c.kind, 0) + 1
        shown = ", ".join(f"{k} {v}" for k, v in sorted(kinds.items()))
        print(f"  {split:5s} {n:4d} clips {minutes:6.1f} min ({shown})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
