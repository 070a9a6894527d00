"""Where the shipped configs are: cdpr_bringup's config folder (robots' set-ups, motions,
calibrations) and its robots/ (robot files), beside the sources of a checkout or in the
package's share directory of an install space (the ament index)."""
from __future__ import annotations

from functools import lru_cache
from pathlib import Path

from cdpr_control.config import Section, load_yaml, resolve_config

DEFAULT_ROBOT = 'paper_robot.yaml'
DEFAULT_MOTIONS = 'motions.yaml'
# The settled run cdpr-scenario writes beside its bag.
SETTLED_RUN = 'run.yaml'
# The folder beside a graph run's bag where each node wrote its last /diagnostics status.
LAST_DIAGNOSTICS = 'last_diagnostics'


@lru_cache(maxsize=1)
def shipped_folders() -> tuple[Path, ...]:
    roots = [Path(__file__).resolve().parents[1] / 'config']
    try:
        from ament_index_python.packages import get_package_share_directory
        roots.append(Path(get_package_share_directory('cdpr_bringup')) / 'config')
    except (ImportError, LookupError, OSError):
        pass
    return tuple(folder for root in roots for folder in (root, root / 'robots'))


def shipped_calibration_document(fingerprint: str, fidelity: str) -> Section | None:
    """The shipped calibration made on the robot of this fingerprint for this plant, as
    read while looking for it."""
    for folder in shipped_folders():
        for path in sorted(folder.glob('*.yaml')):
            document = load_yaml(path)
            made_on = document.get('calibration')
            if (isinstance(made_on, dict) and made_on.get('robot_fingerprint') == fingerprint
                    and made_on.get('fidelity') == fidelity):
                return Section(document, path)
    return None


def shipped_calibration(fingerprint: str, fidelity: str) -> Path | None:
    """The path of the shipped calibration made on the robot of this fingerprint for this plant."""
    document = shipped_calibration_document(fingerprint, fidelity)
    return None if document is None else Path(document.path)


def config_file(name_or_path: str | Path) -> Path:
    """An existing path as given, else the shipped config of that name."""
    return resolve_config(name_or_path, list(shipped_folders()))
