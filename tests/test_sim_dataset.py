"""simulate-dataset: files, labelme polygons agreeing with the label maps, gravity direction."""

from __future__ import annotations

import csv
from pathlib import Path

import cv2
import numpy as np

from gaitnet.config import load_config
from gaitnet.io.labelme_io import read_labelme, read_labels_txt
from gaitnet.sim.config import SimConfig
from gaitnet.sim.dataset import simulate_dataset

CONFIG = Path(__file__).parents[1] / "configs" / "sim" / "tiny.yaml"


def test_dataset_frames_labels_and_gravity(tmp_path: Path) -> None:
    cfg = load_config(SimConfig, CONFIG)
    result = simulate_dataset(
        cfg, 3, seed=7, out_dir=tmp_path / "ds", labelme=True, pitch_range_deg=(68.0, 72.0)
    )
    root = result.path
    assert read_labels_txt(root / "labels.txt")["foot"] == 1
    rows = list(csv.DictReader((root / "frames.csv").read_text().splitlines()))
    assert len(rows) == 3
    for row in rows:
        name = row["id"]
        rgb = cv2.imread(str(root / "images" / f"{name}.png"))
        depth = cv2.imread(str(root / "depth" / f"{name}.png"), cv2.IMREAD_UNCHANGED)
        labels = cv2.imread(str(root / "labels" / f"{name}.png"), cv2.IMREAD_UNCHANGED)
        assert (
            rgb.shape == (120, 160, 3) and depth.dtype == np.uint16 and labels.shape == (120, 160)
        )
        g = np.array([float(row[k]) for k in ("gravity_cx", "gravity_cy", "gravity_cz")])
        assert abs(np.linalg.norm(g) - 1) < 1e-6
        # Camera pitched p below the horizon: gravity's optical-axis component is sin(p) (±
        # the pelvis tilt/obliquity of a few degrees).
        assert abs(np.degrees(np.arcsin(g[2])) - float(row["pitch_deg"])) < 8.0
        cls, _, image = read_labelme(root / "images" / f"{name}.json")
        assert image == (root / "images" / f"{name}.png").resolve()
        for value in (1, 2):
            truth = labels == value
            if truth.sum() > 200:
                inter = (truth & (cls == value)).sum()
                assert inter / (truth | (cls == value)).sum() > 0.85
    assert 0.0 < result.label_fractions["leg"] < 0.5
