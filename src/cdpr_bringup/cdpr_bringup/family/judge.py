"""How the stack did on a family of robots: each failure run's outcome (the right cable
named, a wrong one, none), whether the cables left could hold the end-effector at rest
where the cable broke (a FAULT there is unavoidable, elsewhere it is not), the safe point
reached, the least remaining tension against τ_min and whether the ticks under it lie
within docs/recovery-tensions.md's allowance; per robot and plant, and in total.
Written as summary.csv (a row per run) and summary.md."""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from cdpr_control.model.dynamics import inverse_dynamics
from cdpr_control.tension_distribution import InfeasibleTensionError
from cdpr_msgs_py.contract import FAULT
from cdpr_twin.models.run_figures import JOLT_S, UNDER_TOLERANCE_N

from ..campaigns.campaign import CSV_COLUMNS, _fmt
from ..runs.settle import NO_CALIBRATION, ScenarioOptions, build_scenario

OUTCOMES = ('right', 'wrong', 'missed', 'not completed')
COLUMNS = ('robot', 'body', 'robot_file', *CSV_COLUMNS, 'outcome', 'cables_could_hold', 'tension_min_bound_n')
# docs/recovery-tensions.md's allowance: a cable left may be under τ_min for at most this
# many control periods within the break's jolt (run_figures.JOLT_S), and this many after
ALLOWED_TICKS_IN_JOLT = 5
ALLOWED_TICKS_AFTER_JOLT = 1
DELAY_PERCENTILE = 95.0


@lru_cache(maxsize=None)
def reference_of(config: str, motions: str, motion: str):
    """The scenario (robot, tension distribution, reference) of a run's motion, forward."""
    return build_scenario(ScenarioOptions(config=config, motions=motions, motion=motion, calibration=NO_CALIBRATION))


def cables_could_hold(config: str, motions: str, motion: str, cable: int, failure_time_s: float) -> bool:
    """Whether tensions within [τ_min, τ_max] of the cables left after `cable` (1-based)
    breaks hold the end-effector at rest at the reference pose of `failure_time_s`: the
    run's own tension distribution on the statics of the robot's body (none where too
    few cables are left to span its degrees of freedom)."""
    scenario = reference_of(config, motions, motion)
    robot, reference = scenario.robot, scenario.reference
    row = reference.index_at(failure_time_s)
    pose = np.concatenate([reference.position_m[row], reference.orientation[row]])
    still = np.zeros(robot.body.degrees_of_freedom)
    try:
        tension = inverse_dynamics(robot, scenario.distribution, pose, still, still, attached=robot.cable_mask([cable - 1]),
                                   nan_where_infeasible=True).tension_n
    except (InfeasibleTensionError, np.linalg.LinAlgError):
        return False
    return bool(np.all(np.isfinite(tension)))


def outcome_of(row: dict) -> str | None:
    if row['cable'] is None:
        return None
    if row['error'] is not None:
        return 'not completed'
    if row['correct_identification']:
        return 'right'
    return 'wrong' if row['identified_cables'] else 'missed'


def judged(row: dict, member) -> dict:
    """The campaign row of one of `member`'s runs, with the family's judgement."""
    row = {**row, 'robot': member.name, 'body': member.robot.body.kind, 'robot_file': str(member.robot_file),
           'tension_min_bound_n': member.robot.tension_min_n, 'outcome': outcome_of(row), 'cables_could_hold': None}
    if row['cable'] is not None and row['failure_time_s'] is not None:
        row['cables_could_hold'] = cables_could_hold(str(member.robot_file), str(member.motions_file), row['motion'],
                                                     row['cable'], row['failure_time_s'])
    return row


def over_allowance(row: dict) -> bool:
    """Whether a run's cables left were under τ_min for longer than the allowance from the
    detection on (a FAULT brakes the motors: what the cables carry then is no recovery's)."""
    if row['mode'] == FAULT:
        return False
    jolt, after = row.get('ticks_under_tension_min_jolt'), row.get('ticks_under_tension_min_after_jolt')
    return (jolt or 0) > ALLOWED_TICKS_IN_JOLT or (after or 0) > ALLOWED_TICKS_AFTER_JOLT


def beyond_allowance(row: dict) -> bool:
    """over_allowance where the cables left could hold the pose the cable broke at."""
    return bool(row['cables_could_hold']) and over_allowance(row)


def unavoidably_under(row: dict) -> bool:
    """over_allowance where they cannot: no tensions in [τ_min, τ_max] hold it there."""
    return row['cables_could_hold'] is False and over_allowance(row)


def figures(rows: list[dict]) -> dict:
    """The figures of some judged rows (of one robot and plant, or more)."""
    failures = [row for row in rows if row['cable'] is not None]
    done = [row for row in failures if row['error'] is None]
    delays = [row['detection_delay_ms'] for row in done if row['detection_delay_ms'] is not None]
    holding = [row for row in done if row['cables_could_hold']]
    faults = [row for row in done if row['mode'] == FAULT]
    # a FAULT brakes the motors: the least tension is the recoveries'
    recovered = [row for row in done if row['mode'] != FAULT and row['min_tension_n'] is not None]
    margins = [row['min_tension_n'] - row['tension_min_bound_n'] for row in recovered]
    tensions = [row['min_tension_n'] for row in recovered]
    free = [row for row in rows if row['cable'] is None]
    return {
        'failure_runs': len(failures),
        **{outcome.replace(' ', '_'): sum(row['outcome'] == outcome for row in failures) for outcome in OUTCOMES},
        'fault_cannot_hold': sum(not row['cables_could_hold'] for row in faults),
        'fault_could_hold': sum(bool(row['cables_could_hold']) for row in faults),
        'could_hold': len(holding),
        'reached_where_held': sum(bool(row['reached_safe_point']) for row in holding),
        'reached': sum(bool(row['reached_safe_point']) for row in done),
        'delay_median_ms': float(np.median(delays)) if delays else None,
        'delay_p95_ms': float(np.percentile(delays, DELAY_PERCENTILE)) if delays else None,
        'delay_max_ms': max(delays) if delays else None,
        'least_tension_n': min(tensions) if tensions else None,
        'least_margin_n': min(margins) if margins else None,
        'under_tension_min': sum(margin < -UNDER_TOLERANCE_N for margin in margins),
        'beyond_allowance': sum(beyond_allowance(row) for row in done),
        'unavoidably_under': sum(unavoidably_under(row) for row in done),
        'failure_free_runs': len(free),
        'false_alarms': sum(bool(row['false_alarm']) for row in free if row['error'] is None),
        'failure_free_not_completed': sum(row['error'] is not None for row in free),
    }


def cases(rows: list[dict]) -> list[dict]:
    """The failure runs the stack did not do right: a wrong or no cable named, a FAULT
    where the cables left could hold the pose, the safe point not reached there, a cable
    left under τ_min beyond the allowance."""
    return [row for row in rows if row['cable'] is not None and (
        row['outcome'] != 'right' or beyond_allowance(row)
        or (row['cables_could_hold'] and (row['mode'] == FAULT or not row['reached_safe_point'])))]


TABLE_HEAD = ('| {} | plant | failure runs | right | wrong | missed | not completed | FAULT: cannot hold / could '
              '| SP reached (where the cables hold) | delay median / p95 / max (ms) | least tension / τ_min (N) '
              '| under τ_min beyond the allowance: could hold / cannot | failure-free runs, false alarms |')
TABLE_RULE = '|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|'


def table_line(label: str, plant: str, found: dict, tension_min_n: float | None) -> str:
    bound = _fmt(tension_min_n, 2) if tension_min_n is not None else 'each'
    return (f'| {label} | {plant} | {found["failure_runs"]} | {found["right"]} | {found["wrong"]} | {found["missed"]} '
            f'| {found["not_completed"]} | {found["fault_cannot_hold"]} / {found["fault_could_hold"]} '
            f'| {found["reached"]} ({found["reached_where_held"]} of {found["could_hold"]}) '
            f'| {_fmt(found["delay_median_ms"], 2)} / {_fmt(found["delay_p95_ms"], 2)} / {_fmt(found["delay_max_ms"], 2)} '
            f'| {_fmt(found["least_tension_n"], 2)} / {bound} | {found["beyond_allowance"]} / {found["unavoidably_under"]} '
            f'| {found["failure_free_runs"]}, {found["false_alarms"]}'
            + (f' ({found["failure_free_not_completed"]} not completed)' if found['failure_free_not_completed'] else '')
            + ' |')


def table(rows: list[dict], members) -> list[str]:
    """The outcome per robot and plant, then per plant and in total over the robots."""
    lines = [TABLE_HEAD.format('robot'), TABLE_RULE]
    plants = list(dict.fromkeys(row['fidelity'] for row in rows))
    for member in members:
        mine = [row for row in rows if row['robot'] == member.name]
        for plant in plants:
            part = [row for row in mine if row['fidelity'] == plant]
            if part:
                lines.append(table_line(f'{member.name} ({member.robot.cable_count} cables)', plant, figures(part),
                                        member.robot.tension_min_n))
    for plant in plants:
        lines.append(table_line('**all**', plant, figures([row for row in rows if row['fidelity'] == plant]), None))
    if len(plants) > 1:
        lines.append(table_line('**all**', 'all', figures(rows), None))
    return lines


def case_line(row: dict) -> str:
    fault = ''
    if row['mode'] == FAULT:
        fault = ', FAULT ' + ('(the cables left could hold the pose)' if row['cables_could_hold'] else
                              '(the cables left cannot hold the pose)')
    return (f'- `{row["robot_file"]}`: cable {row["cable"]} on {row["motion"]} at {row["fail_at_fraction"]:.3f} of '
            f'the move (t = {_fmt(row["failure_time_s"], 4)} s), {row["fidelity"]} plant: {row["outcome"]}, named '
            f'{row["identified_cables"] or "none"}{fault}, SP {"reached" if row["reached_safe_point"] else "not reached"}'
            + (f'; a cable left under τ_min for {row["ticks_under_tension_min_jolt"]} periods within the jolt of '
               f'the detection and {row["ticks_under_tension_min_after_jolt"]} after (least '
               f'{_fmt(row["min_tension_n"], 2)} N)' if beyond_allowance(row) else '')
            + (f'; {row["error"]}' if row['error'] else ''))


def summary_markdown(rows: list[dict], members, drawing: dict, heading: str) -> str:
    found = cases(rows)
    lines = [
        '# Robots drawn from a seed: the stack judged on them', '', heading, '',
        f'{drawing["draws"]} robots drawn, {len(members)} kept; refused: '
        + (', '.join(f'{count} by {why}' for why, count in drawing['refused'].items()) or 'none') + '.', '',
        'Right / wrong / missed: the broken cable named alone, another named, none. FAULT: the supervisor gave up; '
        '"cannot hold" where no tensions within [τ_min, τ_max] of the cables left hold the end-effector at rest at '
        'the pose the cable broke at, "could" where they do. SP reached: all runs, and of those where the cables '
        'could hold the pose. Least tension: of a remaining cable after the break, in the runs not in FAULT (a FAULT '
        'brakes the motors). Beyond the allowance: runs not in FAULT whose cables left were under τ_min, from the '
        f'detection on, more than {ALLOWED_TICKS_IN_JOLT} control periods within {JOLT_S * 1000:g} ms (the break\'s '
        f'jolt and the recovery\'s first step) or more than {ALLOWED_TICKS_AFTER_JOLT} later '
        '(docs/recovery-tensions.md); "could hold" where the cables left hold the pose the cable broke at, '
        '"cannot" where no tensions within the bounds do (a cable goes under τ_min until the recovery has moved '
        'the end-effector to where they can). '
        'Failure-free runs: those the '
        'calibration ran, run again with the supervisor on the calibrated thresholds.', '',
        *table(rows, members), '',
        '## Robots', '',
        '| robot | body | cables | frame (m) | mass (kg) | τ_min / τ_max (N) | motions (shrinks) |',
        '|---|---|---:|---|---:|---|---|',
    ]
    for member in members:
        robot = member.robot
        frame = np.ptp(robot.exit_points_m, axis=0)
        lines.append(f'| [{member.name}]({member.robot_file}) | {robot.body.kind} | {robot.cable_count} '
                     f'| {frame[0]:.2f} × {frame[1]:.2f}, exits {robot.exit_points_m[:, 2].min():.2f}–'
                     f'{robot.exit_points_m[:, 2].max():.2f} high | {robot.mass_kg:g} '
                     f'| {robot.tension_min_n:g} / {robot.tension_max_n:g} | {", ".join(member.motions)} '
                     f'({member.shrinks}) |')
    lines += ['', '## Runs not done right', '']
    lines += [case_line(row) for row in found] or ['none']
    return '\n'.join(lines) + '\n'
