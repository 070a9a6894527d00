"""Where the shipped configs are: the source tree, or the package's share directory."""
from __future__ import annotations

from pathlib import Path

PACKAGE = 'cdpr_bringup'


def config_dir() -> Path:
    """The config folder: beside the sources in a checkout, else share/cdpr_bringup/config."""
    source = Path(__file__).resolve().parents[1] / 'config'
    if source.is_dir():
        return source
    from ament_index_python.packages import get_package_share_directory
    return Path(get_package_share_directory(PACKAGE)) / 'config'


def config_file(name_or_path: str | Path) -> Path:
    """An existing path as given, else the shipped config of that file name."""
    path = Path(name_or_path)
    if path.exists():
        return path
    shipped = config_dir() / path.name
    if shipped.exists():
        return shipped
    raise FileNotFoundError(f'no config {name_or_path!s} (looked in {config_dir()})')


DEFAULT_ROBOT = 'paper_robot.yaml'
DEFAULT_MOTIONS = 'motions.yaml'
