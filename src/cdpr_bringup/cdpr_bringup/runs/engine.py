"""The in-process engine: the graph's core classes in one loop, without DDS.

Per cycle k, as the node graph does it: the plant reports θ, θ̇ (and the torque it
applied); the controller answers with c from the setpoint of tick k (the reference, or
the recovery's: cdpr_control.control.setpoints, as the controller node); the twin computes c_DT
from the same reference and the supervisor judges tick k (cdpr_fdi.supervision.monitor); its verdict
steers the controller from tick k + contract.VERDICT_DELAY_TICKS; the plant steps under
c. The view topics' rows are kept on the view ticks only, as the graph publishes them;
the figures of the end-effector come from every tick (cdpr_twin.models.run_figures), as the
plant simulator computes them.
"""
from __future__ import annotations

import numpy as np

from cdpr_control.control.controller import JointController, JointReference, command_lead_periods
from cdpr_control.control.setpoints import Setpoints
from cdpr_fdi.supervision.monitor import Monitor
from cdpr_fdi.supervision.supervisor import Supervisor, Verdict
from cdpr_msgs_py.contract import VERDICT_DELAY_TICKS
from cdpr_msgs_py.stamps import seconds_to_ns
from cdpr_twin.models.plant import PlantSimulator
from cdpr_twin.models.run_figures import RunFigures
from cdpr_twin.nodes.run_length import RunLength
from cdpr_twin.models.twin import DigitalTwin

from .recording import Recording
from .settle import Scenario


def reference_at(scenario: Scenario, k: int) -> JointReference:
    """The reference of tick k; after the motion it holds the end at rest."""
    table = scenario.reference
    row = min(k, len(table) - 1)
    return JointReference(table.angle_rad[row], table.angular_velocity_rad_s[row],
                          table.feedforward_nm[row])


def steer(setpoints: Setpoints, verdict: Verdict, due_ns: int) -> None:
    """What the supervisor node publishes of a verdict, handed to the controller's setpoints:
    the broken cables and the mode, due from the tick stamped `due_ns`, and the recovery's
    setpoint for that tick."""
    setpoints.verdict(due_ns, verdict.broken_cables, verdict.mode)
    if verdict.tension_setpoint_n is not None:
        setpoints.put_recovery_tensions(due_ns, verdict.tension_setpoint_n)
    if verdict.reference is not None:
        setpoints.put_recovery_reference(due_ns, verdict.reference)


def run_inprocess(scenario: Scenario, supervised: bool = True) -> Recording:
    robot = scenario.robot
    start = scenario.reference.position_m[0]
    plant = PlantSimulator(robot, scenario.plant, start, scenario.failures, scenario.pushes,
                           scenario.start_orientation)
    twin = DigitalTwin(robot, scenario.gains, start, scenario.twin_substeps, scenario.start_orientation,
                       scenario.twin_friction)
    controller = JointController(robot, scenario.gains, scenario.fdi.friction,
                                 command_lead_periods(scenario.fdi.drive_delay_s, scenario.period_s))
    setpoints = Setpoints(controller, exact=True)
    supervisor = (Supervisor(robot, scenario.fdi, scenario.recovery, scenario.distribution,
                             scenario.period_s) if supervised else None)
    monitor = Monitor(twin, supervisor, scenario.period_s)
    period_ns = seconds_to_ns(scenario.period_s)
    cycles, m = scenario.cycles, robot.cable_count
    has_orientation = robot.body.has_orientation
    rows = {name: np.empty((cycles, m)) for name in (
        'angle', 'speed', 'command', 'twin_angle', 'twin_speed', 'twin_torque', 'residual',
        'recovery_reference_angle', 'true_tension')}
    rows.update({name: np.empty((cycles, 3)) for name in ('true_position', 'twin_position')})
    if has_orientation:
        rows.update({name: np.empty((cycles, 4)) for name in ('true_orientation', 'twin_orientation')})
    rows['recovery_reference_angle'][:] = np.nan
    named = None    # the tick whose verdict first named a cable
    table = scenario.reference
    applied = np.zeros(m)
    run_length = RunLength(cycles - 1, scenario.hold_after_cycles)
    ran = 0
    try:
        for k in range(cycles):
            if k > run_length.last_tick:
                break
            stamp = k * period_ns
            reference = reference_at(scenario, k)
            setpoints.put_reference(stamp, reference)
            angle, speed = plant.measure()
            rows['true_position'][k], rows['true_tension'][k] = plant.position_m, plant.tension_n
            if has_orientation:
                rows['true_orientation'][k] = plant.orientation
            command = setpoints.command(stamp, angle, speed)
            if command is None:
                raise RuntimeError(f'tick {k}: no {controller.mode} setpoint from the supervisor')
            twin_output, verdict = monitor.step(k, angle, speed, applied, command, reference)
            if verdict is not None:
                # as the graph's supervisor publishes it: due VERDICT_DELAY_TICKS on
                due = k + VERDICT_DELAY_TICKS
                steer(setpoints, verdict, due * period_ns)
                if verdict.broken_cables and named is None:
                    named = k
                rows['residual'][k] = verdict.residual_nm
                if verdict.reference is not None:
                    rows['recovery_reference_angle'][k] = verdict.reference.angle_rad
                run_length.mode(verdict.mode, due)
            plant.step(command, scenario.period_s)
            applied = command
            rows['angle'][k], rows['speed'][k], rows['command'][k] = angle, speed, command
            rows['twin_angle'][k] = twin_output.angle_rad
            rows['twin_speed'][k] = twin_output.angular_velocity_rad_s
            rows['twin_torque'][k] = twin_output.torque_nm
            rows['twin_position'][k] = twin_output.position_m
            if has_orientation:
                rows['twin_orientation'][k] = twin_output.orientation
            ran = k + 1
    except KeyboardInterrupt:
        pass
    rows = {name: values[:ran] for name, values in rows.items()}
    # the view topics' rows: those of the view ticks, as the graph publishes them (design.md §3)
    viewed = np.arange(0, ran, scenario.view_ticks.every)
    views = {name: rows[name][viewed] for name in ('twin_position', 'true_position', 'true_tension')
             + (('true_orientation', 'twin_orientation') if has_orientation else ())}
    # the reference of each tick that ran (reference_at's rows), taken at once
    held = np.minimum(np.arange(ran), len(table) - 1)
    view_held = held[viewed]
    # the figures of every tick, as the plant simulator computes them tick by tick
    figures = RunFigures(m, scenario.period_s, has_orientation, tension_min_n=robot.tension_min_n)
    figures.take_breaks(plant.broken_at_s)
    if named is not None:
        figures.detection_at(named)
    figures.add_rows(np.arange(ran), rows['true_position'], rows.get('true_orientation'), rows['true_tension'],
                     table.position_m[held], table.orientation[held] if has_orientation else None)
    return Recording(
        time_s=np.arange(ran) * scenario.period_s,
        angle_rad=rows['angle'], angular_velocity_rad_s=rows['speed'], command_nm=rows['command'],
        twin_angle_rad=rows['twin_angle'], twin_angular_velocity_rad_s=rows['twin_speed'],
        twin_torque_nm=rows['twin_torque'], reference_angle_rad=table.angle_rad[held],
        view_time_s=viewed * scenario.period_s,
        twin_position_m=views['twin_position'], reference_position_m=table.position_m[view_held],
        true_position_m=views['true_position'], true_tension_n=views['true_tension'],
        residual_nm=rows['residual'] if supervisor is not None else None,
        recovery_reference_angle_rad=rows['recovery_reference_angle'],
        fdi=supervisor.summary() if supervisor is not None else {},
        interrupted=ran <= run_length.last_tick,
        broken_at_s=dict(plant.broken_at_s),
        figures=figures.summary(),
        **({'true_orientation': views['true_orientation'], 'twin_orientation': views['twin_orientation'],
            'reference_orientation': table.orientation[view_held]} if has_orientation else {}))
