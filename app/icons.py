"""Icons shipped as package data (``app/assets/``), read through :mod:`importlib.resources` so
that a wheel install finds them as well as a source checkout."""

from __future__ import annotations

import atexit
from contextlib import ExitStack
from functools import cache
from importlib import resources
from importlib.resources.abc import Traversable
from pathlib import Path

from PySide6.QtGui import QIcon

_FILES = ExitStack()
atexit.register(_FILES.close)


def asset(name: str) -> Traversable:
    """``app/assets/<name>`` (``name`` may hold ``/``) as a package resource."""
    return resources.files("app").joinpath("assets", *name.split("/"))


def has_asset(name: str) -> bool:
    return asset(name).is_file()


@cache
def asset_path(name: str) -> Path:
    """A file-system path of ``app/assets/<name>`` (extracted once if the package is zipped)."""
    return _FILES.enter_context(resources.as_file(asset(name)))


def icon(name: str) -> QIcon:
    """An icon from ``app/assets/`` (an empty icon if the file is missing)."""
    return QIcon(str(asset_path(name))) if has_asset(name) else QIcon()


def page_icon(title: str) -> QIcon:
    """``icons/<title>.svg`` (lower case, spaces as ``_``), else the generic page icon."""
    slug = title.lower().replace(" ", "_")
    name = f"icons/{slug}.svg"
    return icon(name if has_asset(name) else "icons/page.svg")
