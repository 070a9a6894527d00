"""The soak's verdicts: growth in the second half beyond its bound, a false alarm, too many
late commands or unjudged ticks each fail their target."""
from __future__ import annotations

from cdpr_bringup.bench.soak import MEMORY_KIB_PER_5_MIN, WARM_UP_S, targets

TICKS = 300_000


def figures(**changes) -> dict:
    base = {'minutes': 10.0, 'memory_growth_second_half_kib': {'markers': 0, 'supervisor': 8},
            'ticks_judged': TICKS, 'late_commands': 30, 'unjudged_ticks': 300, 'false_alarms': 0}
    return dict(base, **changes)


def verdicts(**changes) -> dict[str, bool]:
    return {label: met for label, _, _, met in targets(figures(**changes))}


def test_a_quiet_soak_meets_every_target():
    met = verdicts()
    assert met and all(met.values()), met


def test_each_target_fails_on_its_own_figure():
    bound = MEMORY_KIB_PER_5_MIN * (10 * 60 - WARM_UP_S) / 2 / 60 / 5
    assert not verdicts(memory_growth_second_half_kib={'markers': int(bound) + 1})[
        'memory growth, second half, largest']
    assert verdicts(memory_growth_second_half_kib={'markers': int(bound)})['memory growth, second half, largest']
    assert not verdicts(false_alarms=1)['false alarms']
    assert not verdicts(late_commands=TICKS // 500)['late commands']          # 0.2 %
    assert not verdicts(unjudged_ticks=TICKS // 100)['unjudged ticks']        # 1 %
