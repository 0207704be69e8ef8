"""gaitnet: gait measurements and lower-body pose from one waist-worn RGB-D camera + IMU."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("gaitnet")
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0.0.0+unknown"

__all__ = ["__version__"]
