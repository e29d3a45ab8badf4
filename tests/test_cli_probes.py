"""The table of mistakes over the seven commands (issues 102 and 104): each line exits 2 with one
line on stderr, `error: ...` naming what is wrong, before any work starts and writing nothing;
`--help` exits 0. The lines run in forks of one process (tests/cli_probes.py), so the table costs
one import of JAX."""

import json
import os
import re
import subprocess
import sys

import pytest

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SMOKE = '--config=door_open.py:smoke'

PROBES = [  # (argv: command first, words the one line must hold)
    (['train'], ['--config', '--workdir', 'must have a value']),
    (['train', 'nosuchmode', '--workdir=run'], ["unknown mode 'nosuchmode'", 'ablations']),
    (['train', '--workdir=run', '--config=door_opn.py:quick'],
     ['--config=door_opn.py:quick', 'no such config file', 'door_open.py']),
    (['train', '--workdir=run', '--config=door_open.py:nosuch'], ["'nosuch'", "'smoke'"]),
    (['train', '--workdir=run', '--config=door_open_online.py:nosuch'], ["'nosuch'", "'finetune'"]),
    (['train', '--workdir=run', '--config=mt10.py:quick'], ["'quick'", 'mt10.py', "'smoke'"]),
    (['train', '--workdir=run', SMOKE, '--config.train.num_step=5'],
     ["'config.train.num_step'", "did you mean 'config.train.num_steps'?"]),
    (['train', '--workdir=run', SMOKE, '--config.plan.nosuch=1'],
     ['--config.plan.nosuch', "'config.plan.nosuch'", 'no field']),
    (['train', '--workdir=run', SMOKE, '--config.nosect.x=1'], ["'config.nosect'", 'no field']),
    (['train', '--workdir=run', SMOKE, '--config.objective.hidden=8'],  # The section's old name.
     ['--config.objective.hidden', "'config.objective'", 'now config.critic']),
    (['train', '--workdir=run', SMOKE, '--config.train.learning_rate=nan'],
     ['config.train.learning_rate', 'NaN']),
    (['train', '--workdir=run', SMOKE, '--config.train.batch_size=abc'],
     ["--config.train.batch_size: 'abc' is not an integer"]),
    (['train', '--workdir=run', SMOKE, '--config.train.learning_rate=fast'],
     ["--config.train.learning_rate: 'fast' is not a number"]),
    (['train', '--workdir=run', SMOKE, '--config.plan.safe_selection=yes'],
     ["--config.plan.safe_selection", "'yes' is not True or False"]),
    (['train', '--workdir=run', SMOKE, '--config.task=door-opn-v3'], ["'door-opn-v3'"]),
    (['train', '--workdir=run', SMOKE, '--config.data.preset=bogus'],
     ['config.data.preset', "'bogus'", "'mixed'", "'weak'"]),
    (['train', '--workdir=run', '--config=door_open_online.py:smoke',
      '--config.train.batch_size=16'],
     ['config.train.batch_size (16)', '12 windows', 'config.online.seed_steps=40']),
    (['train', '--workdir=run', SMOKE, '--nosuch=1'], ["Unknown command line flag 'nosuch'"]),
    (['train', '--workdir=notdir', SMOKE], ['--workdir=notdir is a file, not a run directory']),
    (['train', '--workdir=notdir/run', SMOKE], ['--workdir=notdir/run cannot be a run directory']),
    (['train', '--workdir=/proc/run', SMOKE], ['--workdir=/proc/run cannot be a run directory']),
    (['train', '--workdir=run', SMOKE, '--seeds=0,1', '--config.train.num_seeds=2'],
     ['drop --config.train.num_seeds=2']),
    (['train', 'ablations', '--workdir=run', '--variants=ldmpc,nope'], ["unknown variants ['nope']"]),
    (['evaluate'], ['--workdir', 'must have a value']),
    (['evaluate', 'nosuchmode'], ["unknown mode 'nosuchmode'", 'selection']),
    (['evaluate', '--workdir=missing'], ['no config.json in missing']),
    (['evaluate', '--workdir=empty'], ['no config.json in empty']),
    (['evaluate', '--workdir=cfg', '--out=e.json'], ['no checkpoint', 'cfg']),
    (['evaluate', '--workdir=cfg', '--episodes=0'], ['--episodes must be between 1 and 100,000']),
    (['evaluate', '--workdir=cfg', '--episodes=1000000000000'], ['--episodes must be between']),
    (['evaluate', '--workdir=cfg', '--modes=plan,nosuch'], ["unknown --modes ['nosuch']"]),
    (['evaluate', '--workdir=cfg', '--splits=test'], ["unknown --splits ['test']"]),
    (['evaluate', '--workdir=cfg', '--seeds=a,b'], ["--seeds: 'a' is not an integer"]),
    (['evaluate', '--workdir=cfg', '--out=exists.json'], ['exists.json exists', '--overwrite']),
    (['evaluate', '--workdir=cfg', '--out=notdir/x.json'], ['notdir/x.json cannot be written']),
    (['evaluate', 'bc', '--steps=0'], ['--steps must be >= 1, got 0']),
    (['collect', 'nosuchmode'], ["unknown mode 'nosuchmode'", 'tasks']),
    (['collect', '--out=exists.npz'], ['exists.npz exists', '--overwrite']),
    (['collect', '--out=notdir/x.npz'], ['notdir/x.npz cannot be written']),
    (['collect', '--out=new.npz', '--task=door-opn-v3'], ["'door-opn-v3'"]),
    (['collect', '--out=new.npz', '--episodes=0'], ['--episodes must be >= 1, got 0']),
    (['collect', '--out=new.npz', '--preset=strong'], ['--preset', 'expert|medium|weak|mixed']),
    (['collect', '--out=new.npz', '--action_repeat=0'], ['--action_repeat must be >= 1']),
    (['report'], ['give one or more evaluation JSONs']),
    (['report', 'nosuchmode'], ["unknown mode 'nosuchmode'", 'records']),
    (['report', 'missing.json'], ['cannot read missing.json']),
    (['report', 'exists.json'], ['cannot read exists.json']),
    (['report', '--check=missing.json'], ['cannot read missing.json']),
    (['report', '--check=exists.json'], ['cannot read exists.json']),
    (['report', 'curves', '--workdir=missing', '--out=c.png'], ['--workdir=missing', 'no run']),
    (['report', 'records', '--workdir=missing', '--out=rec'], ['no run directory missing']),
    (['diagnose'], ['--workdir', 'must have a value']),
    (['diagnose', 'nosuchmode'], ["unknown mode 'nosuchmode'", 'trace']),
    (['diagnose', '--workdir=missing'], ['no config.json in missing']),
    (['diagnose', '--workdir=cfg', '--episodes=0'], ['--episodes must be >= 1, got 0']),
    (['diagnose', '--workdir=cfg', '--stride=0'], ['--stride must be >= 1, got 0']),
    (['diagnose', '--workdir=cfg', '--ks=0,4'], ['--ks must be integers >= 1']),
    (['diagnose', 'trace', '--workdir=cfg', '--episodes=x'], ["--episodes: 'x' is not an integer"]),
    (['benchmark_planning', 'nosuchmode'], ["unknown mode 'nosuchmode'", 'evaluation']),
    (['benchmark_planning', '--variants=nosuch'], ["unknown variants ['nosuch']"]),
    (['benchmark_planning', '--widths=huge'], ["unknown widths ['huge']"]),
    (['benchmark_planning', '--repeats=0'], ['--repeats must be >= 1, got 0']),
    (['benchmark_planning', '--config=door_opn.py'], ['--config=door_opn.py', 'no such config']),
    (['benchmark_planning', '--out=notdir/b.json'], ['notdir/b.json cannot be written']),
    (['benchmark_training', 'nosuchmode'], ["unknown mode 'nosuchmode'", 'versions']),
    (['benchmark_training', '--repeats=0'], ['--repeats and --online_waves must be at least 1']),
    (['benchmark_training', '--configs=door_opn.py:cpu'], ['--configs=door_opn.py:cpu', 'no such']),
    (['benchmark_training', '--online_seeds=0'], ['--online_seeds: 0 is below 1']),
    (['benchmark_training', '--online_breakdown=1'], ['door_open.py:cpu', 'is offline']),
    (['benchmark_training', '--online_breakdown=x'], ["--online_breakdown: 'x' is not an integer"]),
    (['benchmark_training', '--out=notdir/b.json'], ['notdir/b.json cannot be written']),
    (['benchmark_training', 'versions', '--baseline=missing'], ['--baseline=missing']),
]
COMMANDS = ['train', 'evaluate', 'collect', 'report', 'diagnose', 'benchmark_planning',
            'benchmark_training']
HELP = [[c, '--help'] for c in COMMANDS]
LOG = re.compile(r'^([IWEF]\d{4} |WARNING|INFO:|[A-Z]+:absl:)')  # Library log lines.


def _setup(folder):
  """The files the probes name: an earlier result of each kind, a file where a folder is meant,
  an empty folder, and a workdir with a config and no checkpoint."""
  from ld_mpc_jax.configs import door_open
  from ld_mpc_jax.learn import checkpointing
  (folder / 'exists.npz').write_bytes(b'an earlier dataset')
  (folder / 'exists.json').write_text('an earlier result')
  (folder / 'notdir').write_text('a file')
  (folder / 'empty').mkdir()
  checkpointing.save_config(door_open.get_config('smoke'), str(folder / 'cfg'))


def _tree(folder):
  """Every folder and file under `folder`, files with their bytes."""
  out = []
  for d, dirs, files in os.walk(folder):
    out += [(os.path.relpath(os.path.join(d, x), folder), None) for x in dirs]
    out += [(os.path.relpath(os.path.join(d, f), folder), open(os.path.join(d, f), 'rb').read())
            for f in files]
  return sorted(out, key=lambda item: item[0])


@pytest.fixture(scope='module')
def outcomes(tmp_path_factory):
  folder = tmp_path_factory.mktemp('probes')
  _setup(folder)
  before = _tree(folder)
  argvs = [p for p, _ in PROBES] + HELP
  done = subprocess.run([sys.executable, os.path.join(REPO, 'tests', 'cli_probes.py'),
                         str(folder)], input=json.dumps(argvs), capture_output=True, text=True,
                        timeout=600, env=dict(os.environ, PYTHONPATH=REPO))
  assert done.returncode == 0, done.stderr[-3000:]
  return dict(zip(map(tuple, argvs), json.loads(done.stdout))), before, _tree(folder)


def test_at_least_five_mistakes_per_command():
  for command in COMMANDS:
    assert sum(p[0] == command for p, _ in PROBES) >= 5, command


@pytest.mark.parametrize('argv,words', PROBES, ids=[' '.join(p) for p, _ in PROBES])
def test_a_mistake_is_one_line_and_exit_code_2(outcomes, argv, words):
  out = outcomes[0][tuple(argv)]
  lines = [l for l in out['stderr'].splitlines() if l.strip() and not LOG.match(l)]
  assert out['code'] == 2, out['stderr'][-3000:]
  assert len(lines) == 1 and lines[0].startswith('error: '), out['stderr'][-3000:]
  assert all(w in lines[0] for w in words), lines[0]
  assert '\\' not in lines[0]  # No repr of an exception's text.


def test_no_mistake_wrote_or_replaced_a_file(outcomes):
  _, before, after = outcomes
  assert after == before


@pytest.mark.parametrize('command', COMMANDS)
def test_help_exits_0_and_names_the_command(outcomes, command):
  """Issue 104: every command's --help exited 1 (absl's default)."""
  out = outcomes[0][(command, '--help')]
  assert out['code'] == 0, out['stderr'][-3000:]
  assert f'experiments.{command}' in out['stderr']
