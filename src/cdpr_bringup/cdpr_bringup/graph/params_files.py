"""cdpr-params --out DIR [cdpr-graph's options]: one ros__parameters file per node, the
run settled as cdpr-graph settles it, for starting nodes by hand:
`ros2 run cdpr_fdi supervisor --ros-args --params-file DIR/supervisor.yaml`.

The files shipped in config/params/ are the default run's (the paper robot, the circle,
lockstep, the elastic plant): `cdpr-params --out src/cdpr_bringup/config/params` writes
them again.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import yaml

from ..cli import command
from .launcher import parser, requested_graph

class _Dumper(yaml.SafeDumper):
    """Multi-line texts (robot_description) as YAML blocks, readable as the robot file was."""


_Dumper.add_representer(str, lambda dumper, text: dumper.represent_scalar(
    'tag:yaml.org,2002:str', text, style='|' if '\n' in text else None))

HEADER = ('# Written by cdpr-params: the run {run}, settled as cdpr-graph settles it.\n'
          '# Start the node with --ros-args --params-file {name}.yaml\n')


def parameter_files(args: argparse.Namespace) -> dict[str, str]:
    """Node name → the text of its parameters file, for cdpr-graph's options `args`
    (without the start handshake, which only a launcher can know)."""
    plant = args.fidelity or "the set-up's"
    run = (f'{args.motion} on {args.config} ({plant} plant, {args.clock}'
           + (f', cable(s) {args.fail_cable} breaking' if args.fail_cable else '') + ')')
    return {spec.name: HEADER.format(run=run, name=spec.name)
            + yaml.dump({'/**': {'ros__parameters': {
                name: value for name, value in spec.parameters.items() if name != 'matches'}}},
                Dumper=_Dumper, sort_keys=False)
            for spec in requested_graph(args)[0]}


@command('cdpr-params')
def main(argv=None):
    options = parser()
    options.prog, options.description = 'cdpr-params', __doc__.split('\n\n')[0]
    options.add_argument('--out', required=True, help='folder for the <node>.yaml files')
    args = options.parse_args(argv)
    files = parameter_files(args)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    for name, text in files.items():
        (out / f'{name}.yaml').write_text(text)
    print(f'cdpr-params: {", ".join(sorted(files))} in {out}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
