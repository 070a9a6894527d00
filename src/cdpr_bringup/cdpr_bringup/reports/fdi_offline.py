"""cdpr-fdi-offline BAG: failure detection and identification on a recorded bag.

Replays /cdpr/joint_states, /cdpr/effort_command and /cdpr/reference of any bag of this
graph — simulated, or recorded on a real robot through a driver that honours the topic
contract — through the digital twin and the supervisor (detection only), and prints
and saves the verdict: when the alarm rose, when and which cables were named, and the
delay after the failure when the bag says when that was.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from cdpr_control.config import load_section
from cdpr_control.control.controller import JointReference, PdGains
from cdpr_control.model.friction import FrictionModel
from cdpr_control.setup.robot_file import load_robot
from cdpr_control.tension_distribution import configured_tension_distribution
from cdpr_fdi.settings.config import load_fdi_config, load_recovery_config
from cdpr_fdi.supervision.offline import RecordedTick, replay
from cdpr_msgs_py import contract
from cdpr_msgs_py.stamps import NANOSECONDS

from ..bags.bag_io import read_messages, read_topics, recording_from_bag
from ..cli import command
from ..paths import DEFAULT_ROBOT, config_file
from ..runs.metrics import statuses_beside, take_statuses
from .report import failure_of


def parse_args(argv=None):
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument('bag', help='rosbag2 folder')
    parser.add_argument('--config', default=DEFAULT_ROBOT, help='robot YAML the bag was recorded with')
    parser.add_argument('--calibration', help='detector thresholds (cdpr-calibrate); default: the '
                        'config file\'s, which are for a noise-free plant')
    parser.add_argument('--detector', choices=['threshold', 'cusum'])
    parser.add_argument('--epsilon', type=float, metavar='NM')
    parser.add_argument('--coulomb-friction', type=float, metavar='NM',
                        help='the motors\' Coulomb friction the FDI assumes (0 for the rigid plant)')
    parser.add_argument('--namespace', default=contract.DEFAULT_NAMESPACE)
    parser.add_argument('--out', help='write the verdict as JSON here')
    return parser.parse_args(argv)


def recorded_ticks(bag: Path, namespace: str) -> tuple[list[int], list[RecordedTick]]:
    """Stamps (ns) and ticks that have a state, a command and a reference, in order."""
    names = {key: f'{namespace}/{key}' for key in
             (contract.JOINT_STATES, contract.EFFORT_COMMAND, contract.REFERENCE)}
    found = read_topics(bag, list(names.values()))
    states, commands, references = (found[names[key]] for key in
                                    (contract.JOINT_STATES, contract.EFFORT_COMMAND, contract.REFERENCE))
    stamps = sorted(set(states) & set(commands) & set(references))
    if not stamps:
        raise ValueError(f'{bag}: no tick has a state, a command and a reference')
    ticks = [RecordedTick(states[s].position, states[s].velocity, states[s].effort, commands[s].effort,
                          JointReference(references[s].position, references[s].velocity,
                                         references[s].effort))
             for s in stamps]
    return stamps, ticks


@command('cdpr-fdi-offline')
def main(argv=None):
    args = parse_args(argv)
    bag = Path(args.bag)
    config = config_file(args.config)
    robot = load_robot(config)
    control = load_section(config, 'control')
    period = control.number('period_s', positive=True)
    fdi = load_fdi_config(config, robot, config_file(args.calibration) if args.calibration else None)
    fdi = fdi.with_overrides(args.detector, args.epsilon, args.coulomb_friction)
    stamps, ticks = recorded_ticks(bag, args.namespace)
    twin = load_section(config, 'twin')
    verdict = replay(ticks, robot, PdGains.from_section(robot, control), twin.integer('substeps', minimum=1),
                     FrictionModel.of_twin(twin, control), fdi,
                     load_recovery_config(config, robot),
                     configured_tension_distribution(control, robot), period)
    recording = recording_from_bag(bag, args.namespace)
    take_statuses(recording, statuses_beside(bag, read_messages(bag, [contract.DIAGNOSTICS])[contract.DIAGNOSTICS]),
                  None)
    failure_time, true_broken, source = failure_of(bag, recording)

    def time_of(tick):
        return None if tick is None else stamps[tick] / NANOSECONDS

    detection = time_of(verdict.identified_tick)
    result = {
        'bag': str(bag), 'detector': fdi.detector, 'epsilon_nm': fdi.epsilon_nm,
        'ticks_replayed': verdict.ticks,
        'alarm_time_s': time_of(verdict.alarm_tick),
        'detection_time_s': detection,
        'identified_cables': verdict.identified_cables,
        'failure_time_s': failure_time, 'true_broken_cables': true_broken,
        'detection_delay_ms': (None if detection is None or failure_time is None
                               else (detection - failure_time) * 1000.0),
        'false_alarm': bool(detection is not None and (failure_time is None or detection < failure_time)),
    }
    if detection is None:
        print(f'{bag}: no failure detected in {verdict.ticks} ticks ({fdi.detector} detector)')
    else:
        delay = result['detection_delay_ms']
        print(f'{bag}: cable(s) {verdict.identified_cables} broken, detected at {detection:.3f} s'
              + ('' if delay is None else f', {delay:.1f} ms after the failure')
              + (' — FALSE ALARM' if result['false_alarm'] else ''))
    print(f'  ({source})')
    if args.out:
        Path(args.out).write_text(json.dumps(result, indent=2))
    return 0


if __name__ == '__main__':
    sys.exit(main())
