"""Errors of the visual-inertial filter."""

from __future__ import annotations

from gaitnet.errors import GaitnetError, SessionError


class FilterDivergedError(GaitnetError):
    """The filter diverged: a NaN/inf in the nominal state or the covariance, or a covariance
    that is not symmetric positive semi-definite. The message names the time and what failed."""


class SceneError(SessionError):
    """The session does not show what a waist-worn camera sees (:mod:`gaitnet.vio.scene_check`):
    the message lists every problem found."""
