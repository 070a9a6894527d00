"""Where the shipped configs are."""
from cdpr_control.config import resolve_config as config_file

DEFAULT_ROBOT = 'paper_robot.yaml'
DEFAULT_MOTIONS = 'motions.yaml'

__all__ = ['config_file', 'DEFAULT_ROBOT', 'DEFAULT_MOTIONS']
