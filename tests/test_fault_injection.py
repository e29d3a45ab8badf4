"""The fault-injection script's helpers (benchmarks/fault_injection.py) on a fake workdir: what
counts as a complete checkpoint or a write in progress, the damage it does, what it reads from
stderr and how it compares final states. The runs themselves: `python -m
benchmarks.fault_injection` (results/faults/)."""

import os
import random

import numpy as np

from benchmarks import fault_disk
from benchmarks import fault_injection as fi
from benchmarks import fault_runner as fr


def _fake_workdir(root):
  """checkpoints/2 and /4 with a few files each, as orbax lays them out."""
  for step in (2, 4):
    base = root / 'checkpoints' / str(step)
    (base / 'default' / 'd').mkdir(parents=True)
    (base / '_CHECKPOINT_METADATA').write_text('{"ok": true}')
    (base / 'default' / '_METADATA').write_text('x' * 100)
    (base / 'default' / 'd' / 'abc').write_bytes(bytes(range(256)) * 4)
  return str(root)


def test_complete_steps_and_writes_in_progress(tmp_path):
  workdir = _fake_workdir(tmp_path)
  assert fr.complete_steps(workdir) == [2, 4]
  assert not fr.writing_checkpoint(workdir)
  tmp = tmp_path / 'checkpoints' / f'6{fr.TMP_SUFFIX}-1234'
  tmp.mkdir()
  assert fr.complete_steps(workdir) == [2, 4] and fr.writing_checkpoint(workdir)
  assert fr.phase(workdir, '', 12) == 'checkpoint write'
  tmp.rmdir()
  (tmp_path / 'online').mkdir()
  (tmp_path / 'online' / 'buffer_4.npz').write_bytes(b'')
  assert not fr.writing_checkpoint(workdir)  # Its orbax step is there.
  (tmp_path / 'online' / 'buffer_6.npz').write_bytes(b'')  # Saved before its orbax step.
  assert fr.writing_checkpoint(workdir)
  assert fr.complete_steps(str(tmp_path / 'none')) == []


def test_phase_reads_the_progress_bar(tmp_path):
  workdir = _fake_workdir(tmp_path)
  bar = 'train:  42%|####      | 5/12 [00:03<00:04]\rtrain:  50%|#####     | 6/12 [00:04<00:04]'
  assert fr.phase(workdir, bar, 12) == 'training at 6/12'
  assert fr.phase(workdir, 'online:  67%|###| 80/120 [00:09]', 120) == 'acting/updates at 80/120'
  assert fr.phase(str(tmp_path / 'new'), 'compiling', 12) == 'startup'
  assert fr.phase(workdir, bar, 4) == 'final evaluation'  # Step 4 is the last one.
  (tmp_path / 'report.json').write_text('{}')
  assert fr.phase(workdir, bar, 4) == 'report written'


def test_damage_deletes_or_truncates_one_file_of_one_step(tmp_path):
  actions = set()
  for seed in range(12):
    workdir = _fake_workdir(tmp_path / str(seed))
    before = {s: {n: os.path.getsize(os.path.join(workdir, 'checkpoints', str(s), n))
                  for n in fr.checkpoint_files(workdir, s)} for s in (2, 4)}
    hurt = fr.damage(workdir, random.Random(seed))
    actions.add(hurt['action'])
    path = os.path.join(workdir, 'checkpoints', str(hurt['step']), hurt['file'])
    assert hurt['size'] == before[hurt['step']][hurt['file']]
    if hurt['action'] == 'delete':
      assert not os.path.exists(path) and hurt['text'].startswith('delete ')
    else:
      assert os.path.getsize(path) == hurt['left'] < hurt['size']
    changed = [(s, n) for s in (2, 4) for n, size in before[s].items()
               if not os.path.exists(os.path.join(workdir, 'checkpoints', str(s), n))
               or os.path.getsize(os.path.join(workdir, 'checkpoints', str(s), n)) != size]
    assert changed == [(hurt['step'], hurt['file'])]  # That file, and no other.
  assert actions == {'delete', 'truncate'}


def test_read_stderr_finds_tracebacks_skipped_steps_and_error_lines():
  text = ('train: 10%|#| 1/12\rwarning: checkpoint step 12 in /w/checkpoints skipped, '
          'ValueError: truncated; trying an earlier one\nerror: no intact checkpoint\n')
  got = fr.read_stderr(text)
  assert got['skipped'] == [12] and got['skip_reasons'] == ['ValueError: truncated']
  assert got['errors'] == ['error: no intact checkpoint'] and not got['traceback']
  assert fr.read_stderr('Traceback (most recent call last):\n  File "x"\nKeyError: 1')['traceback']


def test_compare_trees_is_exact():
  want = {'params': {'w': np.arange(6, dtype=np.float32).reshape(2, 3)}, 'step': np.int32(4)}
  same = {'params': {'w': np.arange(6, dtype=np.float32).reshape(2, 3)}, 'step': np.int32(4)}
  assert fr.compare_trees(same, want) == dict(identical=True, max_abs_diff=0.0)
  nudged = {'params': {'w': np.nextafter(want['params']['w'], np.float32(9))},
            'step': np.int32(4)}
  got = fr.compare_trees(nudged, want)
  assert not got['identical'] and 0 < got['max_abs_diff'] < 1e-5
  assert fr.compare_trees({'params': {}}, want)['max_abs_diff'] == float('inf')
  assert fr.state_hash(same) == fr.state_hash(want) != fr.state_hash(nudged)


def test_table_and_summary_count_every_outcome():
  rows = [dict(trial=1, kind='online', fault='SIGKILL', point='3.0 s: startup',
               outcome='resumed from scratch', identical=True, max_abs_diff=0.0, rc=0,
               traceback=False, skipped=[], resumed_from=0, ok=True, final_hash='a'),
          dict(trial=2, kind='online', fault='truncate 120/x to 0 of 9 bytes', point='after',
               outcome='stopped (exit 2, one line; intact checkpoint: 80)', identical=None,
               max_abs_diff=None, rc=2, traceback=False, one_line=True, skipped=[120],
               resumed_from=80, ok=True, final_hash=None, eval_rc=2, eval_checkpoint=None,
               eval_traceback=True)]
  table = fi.markdown(rows).splitlines()
  assert len(table) == 4 and table[2].endswith('| yes | no |')
  assert '(skipped step 120); evaluate: exit 2 | n/a (stopped) | yes |' in table[3]
  s = fi.summary(rows)
  assert s['online kill'] == dict(trials=1, ok=1, identical=1, stopped_one_line=0, tracebacks=0,
                                  checkpoint_not_as_uninterrupted=0,
                                  resumed_from={'0': 1})
  assert s['online damage']['stopped_one_line'] == 1 and s['online damage']['tracebacks'] == 1
  assert s['distinct_final_states_per_resume_step'] == {'online from 0': 1}


def test_an_error_line_after_a_progress_bar_is_read_as_one():
  text = ('train:  50%|#####     | 6/12 [00:12<00:12,  2.09s/it, loss=170.500]error: no space left '
          'on the device of /w (writing checkpoints/6.orbax-checkpoint-tmp/x): checkpoint step 4 '
          'and those before it are kept in /w/checkpoints; free some space and rerun the same '
          'command to resume from it\n')
  got = fr.read_stderr(text)
  assert got['errors'] == [text[text.index('error:'):].strip()] and not got['traceback']
  first = fault_disk.first_stop(dict(got, rc=2), '/w')
  assert first['first_stop_ok'] and first['first_outcome'] == (
      'stopped (exit 2, one line naming the full disk, writing checkpoints/6.orbax-checkpoint-tmp)')
  glued = fault_disk.first_stop(dict(rc=2, traceback=True, errors=got['errors']), '/w')
  assert not glued['first_stop_ok'] and 'NOT one line' in glued['first_outcome']


def test_a_disk_full_trial_needs_the_one_line_stop_and_the_resume():
  row = dict(kind='online', fault='disk full (900 KiB tmpfs)', disk_kib=900, first_rc=2,
             first_stop_ok=True, first_traceback=False, restored_as_reference=True, rc=0,
             traceback=False, identical=True, max_abs_diff=0.0, skipped=[], resumed_from=40,
             final_hash='a', first_outcome='stopped (exit 2, one line naming the full disk, '
             'writing checkpoints/80.orbax-checkpoint-tmp)', trial=1, point='checkpoints at '
             'the stop: [40]', outcome='resumed from 40', restored_step=40)
  assert fi.group_of(row) == 'disk full' and fr.verdict(row)
  assert not fr.verdict(dict(row, first_stop_ok=False))  # A traceback or no line: not ok.
  assert not fr.verdict(dict(row, identical=False))  # Resumed elsewhere: not ok.
  assert fr.verdict(dict(row, first_rc=0, first_stop_ok=False))  # The disk did not fill.
  line = fi.markdown([row]).splitlines()[2]
  assert line.startswith('| 1 | online | disk full (900 KiB tmpfs) | checkpoints at the stop')
  assert ('writing checkpoints/80.orbax-checkpoint-tmp); after freeing space: resumed from 40, '
          'its checkpoint as uninterrupted | yes | no |') in line
  assert fi.summary([dict(row, ok=fr.verdict(row))])['online disk full']['ok'] == 1


def test_top_up_leaves_the_margin_free(tmp_path, monkeypatch):
  free = {'kib': 10}
  monkeypatch.setattr(fault_disk.os, 'statvfs', lambda path: type(
      'S', (), dict(f_bavail=free['kib'], f_frsize=1024))())
  ballast = str(tmp_path / 'ballast')
  fault_disk.top_up(ballast, 4)
  assert os.path.getsize(ballast) == 6 * 1024
  free['kib'] = 3  # Below the margin already: nothing more.
  fault_disk.top_up(ballast, 4)
  assert os.path.getsize(ballast) == 6 * 1024
