"""Tension distribution methods behind one interface (one module per method).

Rooms it may import: geometry.
"""
from cdpr_control.tension_distribution.base import InfeasibleTensionError, TensionDistribution, floored_fit, minimum_norm
from cdpr_control.tension_distribution.bounded_minimum_norm import BoundedMinimumNorm
from cdpr_control.tension_distribution.floored_least_squares import FlooredLeastSquares
from cdpr_control.tension_distribution.lowered_floor import LoweredFloor, largest_floors
from cdpr_control.tension_distribution.pseudo_inverse import PseudoInverse

METHODS = {method.name: method for method in (PseudoInverse, BoundedMinimumNorm)}


def make_tension_distribution(name: str, tension_min_n: float, tension_max_n: float,
                              **options) -> TensionDistribution:
    """The method called `name` (one of METHODS) with the given bounds."""
    try:
        method = METHODS[name]
    except KeyError:
        raise ValueError(f'unknown tension distribution {name!r}; choose one of '
                         f'{", ".join(METHODS)}') from None
    return method(tension_min_n, tension_max_n, **options)


def configured_tension_distribution(control, robot) -> TensionDistribution:
    """The method the `control` section names (`tension_distribution`), within the
    robot's tension bounds: what the generator, the scenarios and the supervisor use."""
    return make_tension_distribution(control.string('tension_distribution', choices=tuple(METHODS)),
                                     robot.tension_min_n, robot.tension_max_n)


__all__ = ['InfeasibleTensionError', 'TensionDistribution', 'PseudoInverse',
           'BoundedMinimumNorm', 'FlooredLeastSquares', 'LoweredFloor', 'largest_floors', 'METHODS',
           'configured_tension_distribution', 'floored_fit', 'make_tension_distribution', 'minimum_norm']
