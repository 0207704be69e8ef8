"""The printable AprilTag sheet (gaitnet.sim.tag_sheet.printable_sheet, ``gaitnet tags``)."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pupil_apriltags
import pytest
import yaml
from PIL import Image

from gaitnet.errors import InputError
from gaitnet.io.types import AprilTagBoard
from gaitnet.sim.tag_sheet import PAPER_SIZES_M, printable_sheet


def _board(rows: int = 7, cols: int = 5, first_id: int = 0) -> AprilTagBoard:
    return AprilTagBoard("start", "tag36h11", rows, cols, 0.04, 0.012, first_id, np.eye(4))


def test_every_tag_is_found_where_the_board_puts_it() -> None:
    """Known answer: on the A3 sheet at 150 dpi (2480 × 1754 px = 420 × 297 mm) the
    AprilTag library finds every id, each centre within a pixel of the board's layout
    (x right along the columns, y up along the rows: the page seen from above), and each
    tag's side is 40 mm."""
    board = _board(first_id=3)
    dpi = 150
    image = printable_sheet(board, "a3", dpi)
    assert image.shape == (2480, 1754) and image.dtype == np.uint8
    px_m = 0.0254 / dpi
    found = pupil_apriltags.Detector(families="tag36h11").detect(image)
    assert sorted(d.tag_id for d in found) == list(range(3, 38))
    s, g = board.tag_size_m, board.gap_m
    gw, gh = 5 * s + 4 * g, 7 * s + 6 * g
    x0, y1 = (gw - 0.297) / 2, (gh + 0.420) / 2  # the page's left and top edges, board frame
    for d in found:
        x, y, _ = board.tag_centre_in_board(d.tag_id)
        u, v = (x - x0) / px_m - 0.5, (y1 - y) / px_m - 0.5
        assert np.hypot(d.center[0] - u, d.center[1] - v) < 1.0
        side = np.linalg.norm(d.corners[1] - d.corners[0]) * px_m
        assert side == pytest.approx(0.04, abs=2 * px_m)


@pytest.mark.parametrize(
    ("board", "paper", "dpi", "message"),
    [
        (_board(), "a4", 300, "do not fit on A4 (210 × 297 mm)"),
        (_board(first_id=580), "a3", 300, "tag36h11 has ids 0–586 only"),
        (_board(rows=2, cols=2), "a5", 300, "expected one of a4, a3, letter"),
        (_board(rows=2, cols=2), "a4", 10, "dpi 10"),
    ],
)
def test_a_sheet_that_cannot_be_printed_is_one_error(board, paper, dpi, message) -> None:
    with pytest.raises(InputError, match=re.escape(message)):
        printable_sheet(board, paper, dpi)
    assert set(PAPER_SIZES_M) == {"a4", "a3", "letter"}


def test_cli_writes_the_sheet_and_its_session_yaml_entry(tmp_path: Path) -> None:
    """``gaitnet tags``: a PNG with its dpi, a PDF of the paper's size, the apriltag_boards
    entry that session.yaml takes (YAML), and one line for a sheet that does not fit."""
    run = [sys.executable, "-m", "gaitnet.cli", "tags"]
    png = tmp_path / "sheet.png"
    out = subprocess.run([*run, "--out", str(png), "--dpi", "100"], capture_output=True,
                         text=True, check=True)  # fmt: skip
    with Image.open(png) as im:
        assert im.size == (1169, 1654) and round(im.info["dpi"][0]) == 100
    entry = yaml.safe_load(out.stdout.split("lies):\n", 1)[1])["apriltag_boards"][0]
    assert entry == {
        "name": "start", "family": "tag36h11", "rows": 7, "cols": 5, "tag_size_m": 0.04,
        "gap_m": 0.012, "first_id": 0, "T_WfromBoard": np.eye(4).astype(int).tolist(),
    }  # fmt: skip
    pdf = tmp_path / "sheet.pdf"
    subprocess.run([*run, "--out", str(pdf), "--dpi", "100"], capture_output=True, check=True)
    assert b"/MediaBox [ 0 0 841.68 1190.88 ]" in pdf.read_bytes()  # 297 × 420 mm in points
    bad = subprocess.run([*run, "--out", str(tmp_path / "a4.png"), "--paper", "a4"],
                         capture_output=True, text=True)  # fmt: skip
    assert bad.returncode == 1 and len(bad.stderr.strip().splitlines()) == 1
    assert "do not fit on A4" in bad.stderr and not (tmp_path / "a4.png").exists()
