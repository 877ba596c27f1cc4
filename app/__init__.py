"""StudioTrack application: Qt main window, run owner (engine thread), CLI and workflows."""

from __future__ import annotations

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("studiotrack")
except PackageNotFoundError:  # running from a source tree that was never installed
    __version__ = "unknown"
