"""Where the shipped configs are: cdpr_bringup's config folder, beside the sources of a
checkout or in the package's share directory of an install space (the ament index)."""
from __future__ import annotations

from functools import lru_cache
from pathlib import Path

from cdpr_control.config import resolve_config

DEFAULT_ROBOT = 'paper_robot.yaml'
DEFAULT_MOTIONS = 'motions.yaml'


@lru_cache(maxsize=1)
def shipped_folders() -> tuple[Path, ...]:
    folders = [Path(__file__).resolve().parents[1] / 'config']
    try:
        from ament_index_python.packages import get_package_share_directory
        folders.append(Path(get_package_share_directory('cdpr_bringup')) / 'config')
    except (ImportError, LookupError, OSError):
        pass
    return tuple(folders)


def config_file(name_or_path: str | Path) -> Path:
    """An existing path as given, else the shipped config of that name."""
    return resolve_config(name_or_path, list(shipped_folders()))
