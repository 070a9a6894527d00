"""The twin fitted to the robot it watches (cdpr_twin.models.fitting, cdpr-identify): a
plant whose motors are off the robot file by factors the test draws, one per motor, is
recovered within the fit's stated uncertainty from the measurements alone; motions that cannot excite a parameter are
refused, naming it."""
from __future__ import annotations

import numpy as np
import pytest
import yaml

from cdpr_bringup.reports import identify
from cdpr_bringup.runs.engine import run_inprocess
from cdpr_bringup.runs.settle import NO_CALIBRATION, ScenarioOptions, build_scenario
from cdpr_twin.models.fitting import MOTOR_PARAMETERS, FitOptions, NotExcited, fit_twin
from cdpr_twin.models.plant import mismatched_robot, true_motors

from conftest import MOTIONS, PAPER_ROBOT

# The parameters' expanded uncertainty, as cdpr-identify states it.
COVERAGE = identify.COVERAGE
FITTING_MOTIONS = ('along-1', 'along-4', 'circle')


def drawn_plant(tmp_path, rng) -> str:
    """A set-up of the paper robot whose elastic plant is off the robot file by drawn
    factors: the end-effector's mass, and each motor's own."""
    def off(least, most, count=None):
        drawn = 1.0 + rng.choice([-1.0, 1.0], count) * rng.uniform(least, most, count)
        return float(drawn) if count is None else drawn.tolist()

    cables = 4
    factors = {'mass': off(0.03, 0.1), 'inertia': off(0.1, 0.25, cables), 'viscous_friction': off(0.2, 0.5, cables),
               'static_friction': rng.uniform(0.3, 0.7, cables).tolist()}
    setup = tmp_path / 'drawn.yaml'
    setup.write_text(yaml.safe_dump({'robot_file': str(PAPER_ROBOT),
                                     'plant': {'elastic': {'mismatch': factors}}}))
    return str(setup)


def scenario(config: str, motion: str, reverse: bool, motions=MOTIONS, fidelity: str = 'elastic'):
    return build_scenario(ScenarioOptions(config=config, motions=str(motions), motion=motion, reverse=reverse,
                                          fidelity=fidelity, seed=0, calibration=NO_CALIBRATION))


def measured(run):
    recording = run_inprocess(run, supervised=False)
    return recording.angle_rad, recording.angular_velocity_rad_s, recording.command_nm


def test_a_drawn_plant_is_recovered_within_the_stated_uncertainty(tmp_path):
    config = drawn_plant(tmp_path, np.random.default_rng(51))
    runs = [scenario(config, motion, reverse) for motion in FITTING_MOTIONS for reverse in (False, True)]
    truth = mismatched_robot(runs[0].robot, runs[0].plant)
    motors = dict(zip(MOTOR_PARAMETERS, true_motors(runs[0].robot, runs[0].plant)))
    assert all(np.ptp(motors[name]) > 0.0 for name in MOTOR_PARAMETERS)    # the motors differ
    control = runs[0].settings.section('control')
    fit = fit_twin(runs[0].robot, [measured(run) for run in runs], runs[0].period_s,
                   FitOptions(coulomb_smoothing_rad_s=control.number('coulomb_smoothing_rad_s')))
    for name in MOTOR_PARAMETERS:
        expected = motors[name]
        assert np.abs(fit.motors[name] - expected).max() > 0.0    # a fit, not the file's value
        np.testing.assert_array_less(np.abs(fit.motors[name] - expected), COVERAGE * fit.uncertainties[name],
                                     err_msg=name)
        # and nearer the truth than the robot file by far
        assert np.all(np.abs(fit.motors[name] - expected) < 0.2 * np.abs(getattr(runs[0].robot.motor, name) - expected))
    assert fit.stribeck_speed_rad_s is None    # the elastic plant has no break-away friction: none is fitted
    # the mass: its statistical uncertainty is a few grams in 3 kg; what the model leaves
    # out (the cables' stretch in the pose the angles give) is ~0.02 %
    assert fit.mass_kg == pytest.approx(truth.mass_kg, rel=1e-3)
    assert abs(runs[0].robot.mass_kg - truth.mass_kg) > 0.01 * truth.mass_kg


def test_the_field_plants_break_away_friction_is_fitted_where_it_is():
    """The field plant's drives: break-away friction near standstill beyond Coulomb's, a
    command delay, a filtered speed estimate, an electromagnet carried. The fit finds the
    break-away excess at its Stribeck speed, and the viscous friction it would otherwise
    bend; the mass with the magnet's."""
    runs = [scenario(str(PAPER_ROBOT), motion, reverse, fidelity='field') for motion in FITTING_MOTIONS
            for reverse in (False, True)]
    plant, control = runs[0].plant, runs[0].settings.section('control')
    motors = dict(zip(MOTOR_PARAMETERS, true_motors(runs[0].robot, plant)))
    fit = fit_twin(runs[0].robot, [measured(run) for run in runs], runs[0].period_s,
                   FitOptions(coulomb_smoothing_rad_s=control.number('coulomb_smoothing_rad_s'),
                              drive_delay_s=plant.command_delay_s))
    assert fit.stribeck_speed_rad_s == plant.drive.stribeck_speed_rad_s
    np.testing.assert_allclose(fit.motors['breakaway_friction_nm'], plant.drive.breakaway_friction_nm, rtol=0.05)
    np.testing.assert_allclose(fit.motors['viscous_friction_nm_s_rad'], motors['viscous_friction_nm_s_rad'], rtol=0.05)
    np.testing.assert_allclose(fit.motors['static_friction_nm'], motors['static_friction_nm'], rtol=0.02)
    assert fit.mass_kg == pytest.approx(mismatched_robot(runs[0].robot, plant).mass_kg, rel=2e-3)


def test_motions_that_do_not_accelerate_the_motors_are_refused_naming_what(tmp_path):
    """A move of a millimetre: the motors barely accelerate, so their inertia cannot be told."""
    motions = tmp_path / 'motions.yaml'
    motions.write_text('motion_defaults: {peak_speed_m_s: 0.5, rest_before_s: 0.2, rest_after_s: 0.2}\n'
                       'motions:\n  nudge: {type: line, start: [0.844, 0.965, 1.25], goal: [0.845, 0.965, 1.25], '
                       'peak_speed_m_s: 0.002}\n')
    runs = [scenario(str(PAPER_ROBOT), 'nudge', reverse, motions) for reverse in (False, True)]
    with pytest.raises(NotExcited, match=r"motor \d's (inertia|viscous friction|Coulomb friction) enough"):
        fit_twin(runs[0].robot, [measured(run) for run in runs], runs[0].period_s)


def test_cdpr_identify_writes_a_robot_file_whose_plant_is_the_same_machine(tmp_path, capsys):
    """From bags: the fitted file names the fitted twin, and its plant's mismatch, restated,
    still makes the drawn plant (to rounding)."""
    from cdpr_bringup.scenario import command
    config = drawn_plant(tmp_path, np.random.default_rng(7))
    runs = []
    for motion in FITTING_MOTIONS:
        out = tmp_path / motion
        assert command.main(['--config', config, '--motions', str(MOTIONS), '--motion', motion, '--engine',
                             'inprocess', '--fidelity', 'elastic', '--quiet', '--out', str(out)]) == 0
        runs.append(str(out))
    fitted = tmp_path / 'fitted.yaml'
    assert identify.main(runs + ['--config', config, '--out', str(fitted)]) == 0
    assert 'cdpr-identify: end-effector mass' in capsys.readouterr().out
    before, after = scenario(config, 'circle', False), scenario(str(fitted), 'circle', False)
    assert mismatched_robot(after.robot, after.plant).mass_kg == pytest.approx(
        mismatched_robot(before.robot, before.plant).mass_kg, rel=1e-5)
    motors_before, motors_after = true_motors(before.robot, before.plant), true_motors(after.robot, after.plant)
    np.testing.assert_allclose(motors_after, motors_before, rtol=1e-5)
    for name, true in zip(MOTOR_PARAMETERS, motors_before):
        # the twin's one motor type: among the motors' (their mean weighted by how well each is known)
        assert true.min() < getattr(after.robot.motor, name) < true.max()
    assert after.twin_friction.coulomb_nm == after.robot.motor.static_friction_nm


def test_a_run_folder_without_every_tick_is_refused_in_one_line(tmp_path, capsys):
    assert identify.main([str(tmp_path / 'nothing'), '--out', str(tmp_path / 'x.yaml')]) == 2
    err = capsys.readouterr().err
    assert err.startswith('cdpr-identify: ') and err.count('\n') == 1, err


def test_on_the_rigid_plant_the_twin_models_no_friction(tmp_path):
    """The rigid plant is the twin's own friction-free model: a twin that models the motors'
    friction (Coulomb and break-away) does so on the elastic plant only."""
    setup = tmp_path / 'setup.yaml'
    setup.write_text(yaml.safe_dump({'robot_file': str(PAPER_ROBOT), 'twin': {
        'coulomb_friction_nm': 0.1, 'breakaway_friction_nm': 0.03, 'stribeck_speed_rad_s': 0.5}}))
    elastic = scenario(str(setup), 'along-1', False).twin_friction
    assert (elastic.coulomb_nm, elastic.breakaway_nm, elastic.stribeck_speed_rad_s) == (0.1, 0.03, 0.5)
    assert scenario(str(setup), 'along-1', False, fidelity='rigid').twin_friction is None
