"""Two groups of points along one axis: Otsu's threshold of their positions.

Used where one blob may be two feet side by side (the segmenter's foot labels,
:mod:`gaitnet.segmentation.postprocess`; the filter's stance-foot pixels,
:mod:`gaitnet.vio.feet`): the positions across the body are bimodal there, and Otsu's
threshold (the split that maximises the between-group variance; N. Otsu, IEEE Trans. SMC 9,
1979) separates the two modes. OpenCV computes it on 8-bit codes of the positions.
"""

from __future__ import annotations

import cv2
import numpy as np

__all__ = ["otsu_split"]


def otsu_split(values: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """Which of ``values`` (n,) lie above Otsu's threshold, the values clipped to
    ``[lo, hi]`` (``lo < hi``: e.g. their 5th and 95th percentiles, so that a few outliers do
    not squeeze the rest into a few codes) and coded to 0–255."""
    values = np.asarray(values, dtype=np.float64)
    codes = np.round(255 * (np.clip(values, lo, hi) - lo) / (hi - lo)).astype(np.uint8)
    threshold, _ = cv2.threshold(codes[None], 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
    return codes > threshold
