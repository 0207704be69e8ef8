"""Tag corners in a grey image from one of two detectors (``AprilTagParams.detector``).

The AprilTag 3 library (package ``pupil-apriltags``; settings :data:`APRILTAG3_SETTINGS`) or
OpenCV's ``cv.aruco`` (on the image enlarged ``params.upsample`` times): both give the
corners in one convention, that of :func:`gaitnet.io.types.tag_corners_in_board`
(:func:`detect_tags`). Detectors are built once per setting and kept; the AprilTag 3 ones are
freed in the order its C library needs (:class:`_AprilTag3`). The board pose and its
covariance are :mod:`gaitnet.vio.apriltags`'s job.
"""

from __future__ import annotations

import atexit
from typing import TYPE_CHECKING, Any

import cv2 as cv
import numpy as np

from gaitnet.errors import ConfigError

if TYPE_CHECKING:
    from gaitnet.vio.apriltags import AprilTagParams

__all__ = ["APRILTAG3_PACKAGE", "APRILTAG3_SETTINGS", "detect_tags"]

_REFINE = {
    "none": cv.aruco.CORNER_REFINE_NONE,
    "subpix": cv.aruco.CORNER_REFINE_SUBPIX,
    "contour": cv.aruco.CORNER_REFINE_CONTOUR,
    "apriltag": cv.aruco.CORNER_REFINE_APRILTAG,
}
_FAMILIES = {"tag36h11": cv.aruco.DICT_APRILTAG_36h11}
#: The AprilTag 3 library's package (PyPI project pupil-apriltags), as pinned in pyproject.toml.
APRILTAG3_PACKAGE = "pupil_apriltags==1.0.4.post11"
#: AprilTag 3 detector settings: full resolution (``quad_decimate`` 2 decodes ~10 of a sheet's
#: 35 tags at 640×480), no blur (``quad_sigma`` 0.8 decodes ~6), edge refinement, the library's
#: default sharpening, one thread (the filter's budget is per core).
APRILTAG3_SETTINGS: dict[str, Any] = {
    "nthreads": 1,
    "quad_decimate": 1.0,
    "quad_sigma": 0.0,
    "refine_edges": 1,
    "decode_sharpening": 0.25,
}
#: Largest number of corrected bits of an AprilTag 3 decode that is kept.
APRILTAG3_MAX_HAMMING = 2


def _aruco_detector(family: str, params: AprilTagParams) -> cv.aruco.ArucoDetector:
    if params.corner_refinement not in _REFINE:
        raise ValueError(
            f"corner_refinement must be one of {sorted(_REFINE)}, got {params.corner_refinement!r}"
        )
    p = cv.aruco.DetectorParameters()
    p.adaptiveThreshWinSizeMin = int(params.adaptive_thresh_win_min)
    p.adaptiveThreshWinSizeMax = int(params.adaptive_thresh_win_max)
    p.adaptiveThreshWinSizeStep = int(params.adaptive_thresh_win_step)
    p.minMarkerPerimeterRate = float(params.min_marker_perimeter_rate)
    p.cornerRefinementMethod = _REFINE[params.corner_refinement]
    p.errorCorrectionRate = float(params.error_correction_rate)
    return cv.aruco.ArucoDetector(cv.aruco.getPredefinedDictionary(_FAMILIES[family]), p)


class _AprilTag3:
    """A ``pupil_apriltags.Detector`` freed in the order the C library needs.

    pupil-apriltags 1.0.4 frees the tag families before the detector, whose destructor still
    reads them: at garbage collection (e.g. at exit) the process can die of a segmentation
    fault. :meth:`close` frees the detector first, then its families, and leaves nothing for
    the binding's own ``__del__`` to free; it runs when this object goes and at exit.
    """

    def __init__(self, det: Any) -> None:
        self.det = det

    def detect(self, img: np.ndarray) -> list[Any]:
        return self.det.detect(img)

    def close(self) -> None:
        det = self.det
        ptr = getattr(det, "tag_detector_ptr", None)
        if ptr is None:
            return
        det.tag_detector_ptr = None  # the binding's __del__ then frees nothing
        det.libc.apriltag_detector_destroy.restype = None
        det.libc.apriltag_detector_destroy(ptr)
        for family, tf in det.tag_families.items():
            destroy = getattr(det.libc, f"{family}_destroy")
            destroy.restype = None
            destroy(tf)
        det.tag_families = {}

    def __del__(self) -> None:
        self.close()


def _apriltag3_detector(family: str, params: AprilTagParams) -> _AprilTag3:
    try:
        import pupil_apriltags  # noqa: PLC0415  (imported when selected)
    except ImportError as exc:
        raise ConfigError(
            f"tags.detector is 'apriltag3' but its package is not installed: "
            f"pip install {APRILTAG3_PACKAGE}, or set tags.detector=aruco"
        ) from exc
    return _AprilTag3(pupil_apriltags.Detector(families=family, **APRILTAG3_SETTINGS))


@atexit.register
def _close_detectors() -> None:
    for det in _DETECTORS.values():
        if isinstance(det, _AprilTag3):
            det.close()


_DETECTORS: dict[tuple[Any, ...], Any] = {}


def _cached_detector(family: str, params: AprilTagParams) -> Any:
    if family not in _FAMILIES:
        raise ValueError(f"unsupported tag family {family!r} (supported: {sorted(_FAMILIES)})")
    if params.detector == "apriltag3":  # settings: the module's constants
        key: tuple[Any, ...] = ("apriltag3", family, *sorted(APRILTAG3_SETTINGS.items()))
        make = _apriltag3_detector
    else:
        key = ("aruco", family, params)
        make = _aruco_detector
    det = _DETECTORS.get(key)
    if det is None:
        det = _DETECTORS[key] = make(family, params)
    return det


def _detect_aruco(
    det: cv.aruco.ArucoDetector, img: np.ndarray, upsample: int
) -> tuple[np.ndarray, np.ndarray]:
    s = int(upsample)
    if s > 1:
        img = cv.resize(img, None, fx=s, fy=s, interpolation=cv.INTER_CUBIC)
    corners, ids, _ = det.detectMarkers(img)
    if ids is None or len(ids) == 0:
        return np.zeros(0, dtype=np.int64), np.zeros((0, 4, 2))
    c = np.asarray(corners, dtype=np.float64).reshape(-1, 4, 2)
    return np.asarray(ids, dtype=np.int64).reshape(-1), (c + 0.5) / s - 0.5


def _detect_apriltag3(det: _AprilTag3, img: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    found = [r for r in det.detect(np.ascontiguousarray(img)) if r.hamming <= APRILTAG3_MAX_HAMMING]
    if not found:
        return np.zeros(0, dtype=np.int64), np.zeros((0, 4, 2))
    # AprilTag 3 lists a tag's corners top-right, top-left, bottom-left, bottom-right as read
    # (counter-clockwise on the image), pixel centres at +0.5: aruco order is [1, 0, 3, 2],
    # minus 0.5 px (tests/test_vio_apriltags.py checks both against tag_corners_in_board).
    c = np.stack([np.asarray(r.corners, dtype=np.float64)[[1, 0, 3, 2]] for r in found])
    return np.array([r.tag_id for r in found], dtype=np.int64), c - 0.5


def detect_tags(
    gray: np.ndarray,
    params: AprilTagParams,
    family: str = "tag36h11",
    roi: tuple[int, int, int, int] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Decode tags in a grey image: ``(ids (n,), corners (n, 4, 2))`` in full-image pixels.

    Whichever ``params.detector``, the corners are in aruco order (top-left, top-right,
    bottom-right, bottom-left as read), pixel centres at integers: those of
    :func:`gaitnet.io.types.tag_corners_in_board`. ``roi = (x0, y0, x1, y1)`` restricts the
    search to that box (``aruco`` finds the same corners there as in the whole image,
    ``apriltag3``'s move by up to ~0.1 px with the box's top row). ``aruco`` enlarges the image
    ``params.upsample`` times first; a point ``u'`` of the enlarged image is
    ``(u' + 0.5) / s − 0.5`` in the original (pixel-centre model). Raises
    :class:`~gaitnet.errors.ConfigError` when ``apriltag3`` is selected and its package is
    missing.
    """
    det = _cached_detector(family, params)
    x0 = y0 = 0
    img = gray
    if roi is not None:
        x0, y0, x1, y1 = roi
        img = gray[y0:y1, x0:x1]
    if img.size == 0:
        return np.zeros(0, dtype=np.int64), np.zeros((0, 4, 2))
    if params.detector == "apriltag3":
        ids, c = _detect_apriltag3(det, img)
    else:
        ids, c = _detect_aruco(det, img, params.upsample)
    return ids, c + np.array([x0, y0], dtype=np.float64)
