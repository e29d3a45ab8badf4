"""LD-MPC on Meta-World door-open-v3.

  python -m experiments.train --config=door_open.py            # reference (paper-sized)
  python -m experiments.train --config=door_open.py:cpu        # trains on a 2-core CPU
  python -m experiments.train --config=door_open.py:quick      # end to end in about 2 minutes
  python -m experiments.train --config=door_open.py:smoke      # seconds, for tests
  python -m experiments.train ablations                               # uses the :ablation preset
"""

import ml_collections

from ld_mpc_jax.configs import base


def resize(c: ml_collections.ConfigDict, width: int, heads: int, blocks: int) -> None:
  """Same architecture, smaller: latent, encoder and blocks of `width`, `blocks` per network."""
  m = c.model
  m.latent_dim = m.encoder_hidden = m.width = width
  m.num_heads = heads
  m.proposal_blocks = m.dynamics_blocks = m.objective_blocks = blocks


def get_config(preset: str | None = None) -> ml_collections.ConfigDict:
  c = base.get_config()
  c.task = 'door-open-v3'
  if preset in (None, '', 'reference'):
    return c
  if preset == 'cpu':
    resize(c, width=128, heads=4, blocks=2)
    c.model.actor_hidden = (128, 128)
    c.critic.hidden = (128, 128)
    c.model.dropout = 0.0  # Short training on plentiful data: dropout only slows fitting.
    # The fast planner: 4 deterministic DDIM steps for the proposal, 1 per transition, 16 of the
    # 64 candidates from the actor prior, and after the first step of an episode the proposal
    # warm-started from the shifted previous plan (re-noised to t = 0.5, 2 denoising steps).
    # On earlier code (lab/log.md, before 2026-11-21) the warm start gave 149 of 150 episodes
    # over 3 evaluation seeds, against 128 without it.
    c.plan.action_steps = 4
    c.plan.dynamics_steps = 1
    c.plan.action_eta = c.plan.dynamics_eta = 0.0
    c.plan.num_prior_candidates = 16
    c.plan.warm_start_steps = 2
    c.plan.warm_start_t = 0.5
    # 4,000 steps of batch 128 took 1,967-4,062 s on the shared 2-core machine (docs/results.md).
    c.train.batch_size = 128
    c.train.learning_rate = 3e-4
    c.train.num_steps = 4_000
    c.train.eval_every = 2_000
    return c
  if preset == 'cpu_pixels':  # :cpu from 48 x 48 RGB frames (issue 105; docs/data.md).
    c = get_config('cpu')
    # 64 x 64 frames at batch 128 made an update 2.10 s on the 2-core AMD EPYC, 48 x 48 at batch 64
    # 0.53 s (results/benchmarks/training_pixels{,48}_epyc.md): three seeds train in 95 min, not about 7 h.
    c.model.image_size = 48
    c.train.batch_size = 64
    c.obs_dim = c.model.image_size ** 2 * c.model.image_channels
    c.model.encoder_type = 'conv'
    c.model.normalize_obs = False  # Pixels in [0, 255]: the encoder scales them itself.
    return c
  if preset == 'ablation':
    # Small, so that experiments.train ablations can run on a 2-core CPU: 3 mixed seeds without the
    # expert seed took about two hours there, two sweep processes side by side (one training
    # 4-16 minutes on one core; docs/ablations.md, Results).
    resize(c, width=64, heads=4, blocks=1)
    c.model.actor_hidden = (64, 64)
    c.critic.hidden = (64, 64)
    c.model.dropout = 0.0
    c.plan.num_candidates = 32
    c.plan.action_steps = 4
    c.plan.dynamics_steps = 2
    c.mppi.num_samples = 64  # TD-MPC2's 512 x 6 iterations is 100x the planner's 32 rollouts.
    c.mppi.num_elites = 8
    c.mppi.num_prior = 8
    c.mppi.iterations = 3
    c.train.batch_size = 128
    c.train.learning_rate = 3e-4
    c.train.warmup_steps = 100
    c.train.num_steps = 3_000
    c.train.eval_every = 3_000  # Only the final evaluation.
    c.train.checkpoint_every = 1_000
    return c
  if preset == 'quick':
    # Every stage of the main job in about two minutes on 2 CPU cores (README): data, training,
    # checkpoints, held-out evaluation of the planner and its baselines, report and plots. Too
    # short to learn the task: its success rates say nothing about the method.
    resize(c, width=32, heads=2, blocks=1)
    c.model.actor_hidden = c.critic.hidden = (32, 32)
    c.model.dropout = 0.0
    c.plan.num_candidates, c.plan.num_prior_candidates = 16, 4
    c.plan.action_steps = c.plan.dynamics_steps = 2
    c.data.episodes = 20
    c.train.batch_size = 64
    c.train.warmup_steps = 20
    c.train.num_steps = 300
    c.train.eval_every = 300
    c.train.checkpoint_every = 150
    c.eval.episodes = 4
    c.eval.batch_size = 4
    c.eval.splits = ('held_out',)
    c.eval.noise_stds = (0.0,)
    c.eval.max_episode_steps = 200
    return c
  if preset == 'smoke':
    resize(c, width=16, heads=2, blocks=1)
    c.model.actor_hidden = (16,)
    c.critic.hidden = (16,)
    c.critic.num_values = 3
    c.critic.rollout_unroll = False  # The update compiles in about a third less time.
    c.model.num_bins = 11
    c.plan.num_candidates = 4
    c.plan.action_steps = 2
    c.plan.dynamics_steps = 2
    c.train.batch_size = 8
    c.train.warmup_steps = 2
    c.train.num_steps = 4
    c.train.log_every = 2
    c.train.eval_every = 4
    c.train.checkpoint_every = 2
    c.data.episodes = 2
    c.eval.episodes = 1
    c.eval.periodic_episodes = 1
    c.eval.max_episode_steps = 20
    c.eval.noise_stds = (0.0,)
    c.eval.batch_size = 2
    return c
  raise ValueError(f"unknown preset {preset!r}: use '' or 'reference', 'cpu', 'cpu_pixels', 'ablation', "
                   "'quick' or 'smoke'")
