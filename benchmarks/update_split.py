"""Where an update's FLOPs go (issue 101): XLA's count of one update step of a config as given,
and with each part left out, so that each part's FLOPs are the difference.

A part is left out through the config (`PARTS`: a loss weight of 0 is not computed,
`critic.latent_rollout=False` drops the model's latent rollout), so the counts are those of
programs the library really compiles. Parts are not additive where one feeds another (the
rollout's latents go through the objective's terms too). Counts only: nothing is run, so the
machine's load does not matter (the scans unrolled as `benchmark_training` counts them).

  python -m experiments.benchmark_training --configs=door_open_online.py:cpu --update_split \
      --out=results/benchmarks/update_split_cpu.json
"""

from typing import Callable, Dict, List, Sequence, Tuple

import ml_collections

from ld_mpc_jax.configs.overrides import with_overrides

# name -> (what it is, the fields that leave it out).
PARTS: Dict[str, Tuple[str, dict]] = {
    'latent_rollout': ("the model's latent rollout: its consistency loss and the objective's "
                       'terms on its latents', {'critic.latent_rollout': False}),
    'dynamics_loss': ("the dynamics' denoising loss (teacher-forced)", {'loss.w_dyn': 0.0}),
    'proposal_loss': ("the proposal's denoising loss", {'loss.w_act': 0.0}),
    'values_3_to_5': ('value members beyond two', {'critic.num_values': 2}),
    'half_batch': ('half the batch', None),  # Fields made from the config (batch_size / 2).
}


def part_fields(config: ml_collections.ConfigDict, name: str) -> dict:
  """The fields that leave part `name` out of `config`'s update."""
  fields = PARTS[name][1]
  if fields is None:  # half_batch
    return {'train.batch_size': max(1, config.train.batch_size // 2)}
  return fields


def split(config: ml_collections.ConfigDict, gflop: Callable[[ml_collections.ConfigDict], float],
          parts: Sequence[str] = tuple(PARTS)) -> List[dict]:
  """[{part, what, fields, gflop, saved_gflop, share}]: the config as given first (part 'all'),
  then each of `parts` left out; `gflop(config)` counts one update step."""
  unknown = [p for p in parts if p not in PARTS]
  if unknown:
    raise ValueError(f'unknown update parts {unknown}; known: {list(PARTS)}')
  base = gflop(config)
  out = [dict(part='all', what='the update as configured', fields={}, gflop=base,
              saved_gflop=0.0, share=0.0)]
  for name in parts:
    fields = part_fields(config, name)
    g = gflop(with_overrides(config, fields))
    out.append(dict(part=name, what=PARTS[name][0], fields=fields, gflop=g,
                    saved_gflop=base - g, share=(base - g) / base))
  return out


def update_gflop(config: ml_collections.ConfigDict) -> float:
  """XLA's FLOPs of one update step of `config` (scans unrolled), in GFLOP; nothing runs."""
  import jax  # pylint: disable=g-import-not-at-top
  from benchmarks.training import random_batch, unrolled_flops  # pylint: disable=g-import-not-at-top
  from ld_mpc_jax.learn.train_state import (  # pylint: disable=g-import-not-at-top
      LearnSettings, create_train_state, make_update)
  learn = LearnSettings.from_config(config)
  abstract = jax.eval_shape(lambda: create_train_state(learn, jax.random.key(0)))
  batch = random_batch(config, config.train.batch_size)
  return unrolled_flops(make_update(learn), abstract, batch, jax.random.key(0))['total'] / 1e9


def markdown(entries: Sequence[dict], spec: str) -> str:
  lines = [f'One update step of `{spec}`, each part left out in turn (XLA cost analysis, scans '
           'unrolled; counts, not timings).', '',
           '| part left out | fields | GFLOP | saved GFLOP | share of the update |',
           '| --- | --- | ---: | ---: | ---: |']
  for e in entries:
    fields = ', '.join(f'`{k}={v}`' for k, v in e['fields'].items()) or '-'
    lines.append(f"| {e['part']} ({e['what']}) | {fields} | {e['gflop']:.3f} | "
                 f"{e['saved_gflop']:.3f} | {100 * e['share']:.0f}% |")
  return '\n'.join(lines) + '\n'
