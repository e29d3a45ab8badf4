"""benchmark_planning keeps what it measured when a run is cut short."""

import json

from benchmarks import planning as benchmark_planning


def _entry(name, variant, latencies_s):
  return dict(name=name, variant=variant, num_params=1_660_000, num_candidates=64, steps='2x1',
              compile_s=6.0, gflop=1.32, gflop_xla=1.37, latencies_ms=list(latencies_s))


def test_partial_results_are_written_and_the_entries_left_as_measured(tmp_path):
  device = dict(name='cpu', platform='cpu', jax='0', loadavg_1min_at_start=0.1)
  entries = [_entry('fast_warm/cpu', 'fast_warm', [0.010, 0.012, 0.030]),
             _entry('mppi', 'mppi', [0.020, 0.024, 0.022])]
  out = tmp_path / 'bench.json'
  benchmark_planning.write_partial(str(out), entries[:1], 100.0, device)
  first = json.loads(out.read_text())
  assert [e['name'] for e in first] == ['fast_warm/cpu']
  assert first[0]['latency_ms']['median'] == 12.0 and first[0]['latency_vs_mppi'] is None
  assert entries[0]['latencies_ms'] == [0.010, 0.012, 0.030]  # Not consumed by finish().
  done = benchmark_planning.write_partial(str(out), entries, 100.0, device)
  assert json.loads(out.read_text()) == done
  assert done[0]['latency_vs_mppi'] == 12.0 / 22.0
  assert '| fast_warm/cpu |' in (tmp_path / 'bench.md').read_text()
