"""LD-MPC trained online on Meta-World door-open-v3 (ld_mpc_jax.runs.online; docs/online.md).

  python -m experiments.train --config=door_open_online.py --workdir=runs/online  # reference size
  python -m experiments.train --config=door_open_online.py:cpu --workdir=runs/online_cpu
  python -m experiments.train --config=door_open_online.py:finetune --workdir=runs/online_ft \
      --config.online.init_from=runs/obj/door_open_medium_window/seed0  # offline-to-online
  python -m experiments.train --config=door_open_online.py:smoke --workdir=/tmp/online  # tests
  python -m experiments.train --config=door_open_online.py:tdmpc2_cpu --workdir=runs/tdmpc2  # control

The networks, planner and losses are door_open.py's (the same preset sizes); `online` says how
the agent gathers its own data. A killed run resumes from its last checkpoint with the same
command.
"""

import ml_collections

from ld_mpc_jax.configs import door_open, overrides


def online_settings() -> ml_collections.ConfigDict:
  """The reference online settings (environment steps count Meta-World's own steps)."""
  o = ml_collections.ConfigDict()
  o.enabled = True
  # An offline run's workdir to start from (its latest checkpoint and its dataset); '' = scratch.
  o.init_from = ''
  # Simulator steps. TD-MPC2's published door-open 0.67 is at 100k decisions = 200k simulator steps.
  o.env_steps = 100_000
  # Where every annealed schedule ends (the demonstrations' share, the executed-action noise,
  # act_schedule='linear'), in simulator steps; 0 = env_steps. A run continued to more steps
  # (--continue_with_changes) keeps its schedules with this set to its first env_steps.
  o.schedule_steps = 0
  o.num_envs = 4  # Environments stepped in lockstep, one episode each per wave.
  o.episode_steps = 500  # Full-length episodes (success does not end them), as the data's.
  # Random-action steps before the first update (from scratch): TD-MPC2 seeds with 5 episodes'
  # worth of steps; here 2 waves of 4 episodes.
  o.seed_steps = 4_000
  # Updates per environment step: TD-MPC2 makes one per decision, 0.5 at action repeat 2.
  o.update_ratio = 0.5
  # Exploration noise on the planner's candidates while acting (never in evaluation): the argmax
  # still picks among them, so noise widens what is tried without acting blindly.
  o.action_noise_std = 0.2  # Gaussian, on the proposal's sequences (then clipped).
  o.prior_noise_std = 0.2  # Gaussian, on the actor-prior candidates' actions (not the first).
  # Pessimism while acting (evaluation keeps plan.pessimism): penalising ensemble disagreement
  # steers away from exactly the unfamiliar states exploration should reach (TD-MPC2 has none).
  # Negative = optimism: mean + |act_pessimism| std, a bonus for what the ensemble disputes.
  o.act_pessimism = 0.0
  # Intrinsic exploration in J while acting (objective.Intrinsic; never in evaluation), for runs
  # without demonstrations. 'constant': act_pessimism and act_disagreement as set; 'linear':
  # both linear from those values at the first planner wave to *_end at env_steps, traced
  # arguments of the plan (no recompiling). OAC (Ciosek et al. 2019) and Plan2Explore keep their
  # bonus constant; the annealing is this project's, like the executed-action noise's.
  o.act_schedule = 'constant'
  o.act_pessimism_end = 0.0  # Optimism (UCB over the value ensemble, as OAC's upper bound) -> 0.
  # Weight in J of the dynamics draws' disagreement about the latents a candidate reaches (sum
  # over the horizon of gamma^i x the variance over draws of z_{i+1}, mean over dimensions):
  # Plan2Explore (Sekar et al. 2020) with the diffusion dynamics' draws as its ensemble. J is in
  # reward units, a latent's variance at most about 1 (RMS-normalised). Needs >= 2 draws.
  o.act_disagreement = 0.0
  o.act_disagreement_end = 0.0  # Its end value under act_schedule='linear'.
  # Weight in J of the learned exploration value (ld_mpc_jax.model.novelty, needs loss.w_novelty
  # > 0): Plan2Explore's novelty learned into a value, so the planner sees it past its horizon;
  # in units of the average candidate's novelty (scaled to mean 1 over the candidates).
  o.act_novelty = 0.0
  o.act_novelty_end = 0.0  # Its end value under act_schedule='linear'.
  # Dynamics rollouts per candidate while acting (0: plan.dynamics_draws, evaluation's): the
  # ensemble of the disagreement term, so evaluation can keep one draw (Plan2Explore: 10 heads).
  o.act_dynamics_draws = 0
  # The diffusion proposal's candidates while acting (evaluation keeps them): False leaves the
  # actor prior's and the search's, to measure whether the proposal adds to exploration (the
  # issue's "does the diffusion proposal explore?"; refined candidates won 86-89% on sparse).
  o.act_proposal = True
  # Safe selection while acting (evaluation keeps plan.safe_selection): off, so that acting
  # departs from the actor prior wherever the argmax says, and the data shows whether it was
  # right; a margin that keeps the actor prior belongs to what is executed when it counts.
  o.act_safe_selection = False
  # The search while acting (evaluation keeps plan.num_gaussian and plan.iterations): broad
  # Gaussian candidates and MPPI refinement rounds widen what is tried; on push's online
  # checkpoints they cost success when evaluating (docs/results.md). :cpu acts with them only.
  o.act_num_gaussian = 0
  o.act_iterations = 0
  # Gaussian noise on the executed action while acting, its std linear from start to end over
  # the run (DDPG/TD3-style action noise, annealed; 0 and 0 = the planner's action as chosen).
  o.exec_noise_start = 0.0
  o.exec_noise_end = 0.0
  # Correlation of that noise from one decision to the next (AR(1), the discrete
  # Ornstein-Uhlenbeck process; stationary std as above): 0 = white noise. DDPG's OU noise
  # (theta 0.15 per step) is 0.85; correlated noise keeps pushing one way for several
  # decisions, as a door needs (Eberhard et al. 2023, colored noise for MPC and RL).
  o.exec_noise_corr = 0.0
  # Who acts after the seed waves: 'plan' (the planner) or 'actor' (the actor prior alone, with
  # the executed-action noise below): does planning while acting make better data?
  o.act_mode = 'plan'
  o.updates_per_call = 1  # Updates per jitted call (lax.scan): fewer dispatches on a CPU.
  # Goal configurations of the training episodes: 'mt1', the 50 of MT1 seed `data.seed` (the
  # scripted data's); 'random', a fresh one per episode from the task's whole random-reset space,
  # as TD-MPC2 trains (its Meta-World wrapper sets `_freeze_rand_vec = False`). Evaluation keeps
  # the held-out goals either way.
  o.train_goals = 'mt1'
  # 'dense': Meta-World's shaped reward; 'sparse': 1 on steps where the task is solved, else 0.
  o.reward = 'dense'
  # Demonstrations (ld_mpc_jax.data.demos), as MoDem (Hansen et al. 2022) and DEMO3 use: N
  # successful episodes of the scripted policy on training goals (or the first N successful
  # episodes of the dataset file `demo_path`), with the run's reward, in their own buffer.
  o.demos = 0  # MoDem and DEMO3: 5.
  o.demo_path = ''
  o.demo_noise_std = 0.1  # Gaussian noise on the scripted actions (the `expert` data level).
  # Share of every batch drawn from the demonstrations, linear over the run (MoDem: 50% -> 25%;
  # RLPD samples offline and online data 50:50).
  o.demo_share_start = 0.5
  o.demo_share_end = 0.25
  # Updates on the demonstrations alone before the first wave (MoDem's BC pretraining; here of
  # every network: proposal, actor prior, dynamics, objective); not counted in update_ratio.
  # With demonstrations, updates start at once and no wave acts at random: the planner acts from
  # the first wave with the proposal pretrained on them, plus the executed-action noise (MoDem's
  # seeding phase acts with its BC-pretrained policy); with demo_seed_actor the seed waves
  # (seed_steps) act with the actor prior alone instead (give it loss.w_demo_bc > 0).
  o.demo_pretrain_updates = 1_000
  o.demo_seed_actor = False
  # Planner environments per vmap (0: one jitted plan per environment, the faster on a 2-core
  # CPU; an accelerator wants them all in one vmap).
  o.plan_chunk = 4
  o.checkpoint_every = 4_000  # Environment steps; checkpoints come at wave ends.
  o.eval_every = 10_000  # Held-out evaluation (eval.periodic_episodes episodes).
  return o


def _cpu(c: ml_collections.ConfigDict) -> None:
  """The `:cpu` online preset: 100k simulator steps at 0.5 updates per step on a 2-core CPU, a
  planner that searches while acting, values that extrapolate, optimism and correlated noise while
  acting (docs/results.md has what each of these changed; it was `:cpu_tanh` until commit
  e421b33)."""
  door_open.resize(c, width=64, heads=4, blocks=1)  # 50k updates must fit (docs/online.md).
  c.model.actor_hidden = c.critic.hidden = (64, 64)
  c.model.dropout = 0.0
  c.train.warmup_steps = 100
  p = c.plan
  # First round: 16 proposal sequences, 8 actor-prior ones; while acting also 32 broad Gaussian
  # ones and 3 MPPI rounds of 32 around 8 elites (TD-MPC2 mixes 24 policy rollouts into 512
  # samples, 6 rounds around 64 elites), at this CPU's budget. Evaluation plans with the proposal
  # and the actor prior only: the broad candidates and the MPPI rounds pick sequences the
  # objective overrates (push: 0.61 with them, 0.77 without, on the same checkpoints).
  p.num_candidates, p.num_prior_candidates = 24, 8
  p.iterations, p.num_refine, p.num_elites = 0, 32, 8
  p.num_gaussian = 0
  c.online.act_num_gaussian, c.online.act_iterations = 32, 3
  # TD-MPC2's targets and policy: values of the current policy, not of the buffer's actions, and
  # its log-std map for the max-Q policy (a tanh into [log_std_min, log_std_max], not a clip:
  # the gradient does not vanish at the bounds).
  c.critic.td_target = 'policy'
  c.critic.actor = 'maxq'
  c.critic.log_std_map = 'tanh'
  # Reward and values learn on the encoder's latents only, not also on the dynamics' latent
  # rollout: 37% of an update's FLOPs, 1.51x the simulator steps per second, and on the same
  # held-out episodes dense door-open 150/150 against 96/150 with it, push 53/150 against 56/150
  # (level; docs/results.md).
  c.critic.latent_rollout = False
  # TD-MPC2's discount heuristic (episode_length / 5 - 1) / (episode_length / 5), clipped to
  # [0.95, 0.995]: 0.95 for its 100-decision Meta-World episodes.
  c.gamma = 0.95
  o = c.online
  # TD-MPC2's training episodes: 100 decisions at action repeat 2 (evaluation keeps
  # Meta-World's 500 steps), so 500 resets in 100k steps instead of 200.
  o.episode_steps = 200
  o.seed_steps = 1_600  # 2 waves of 4 random-action episodes (TD-MPC2: 5 episodes).
  o.update_ratio = 0.5  # TD-MPC2: one update per decision.
  o.updates_per_call = 8
  # Optimism in the face of uncertainty while acting (UCB over the value ensemble; evaluation
  # keeps plan.pessimism): the door's unvisited angles are where the members disagree.
  o.act_pessimism = -1.0
  # Executed-action noise down to TD-MPC2's min_std, correlated over decisions (DDPG's
  # Ornstein-Uhlenbeck theta = 0.15 per decision): noise that keeps pushing one way for several
  # decisions can swing a door open.
  o.exec_noise_start, o.exec_noise_end = 0.3, 0.05
  o.exec_noise_corr = 0.85
  o.plan_chunk = 0
  c.eval.splits = ('held_out',)  # The headline split; train goals at the end cost 10 minutes.


# `:tdmpc2_cpu`, the TD-MPC2 control (issue 100; Hansen et al. 2024, github
# nicklashansen/tdmpc2), built from this library's kinds at `:cpu`'s budget: its width (64),
# batch (128), learning rate, updates per step (0.5 = one per decision), environments (4),
# episodes (200 steps), seed steps (1,600), simulator steps (100k) and gamma (0.95; TD-MPC2's
# heuristic), and as many model rollouts per acting decision as `:cpu`'s (152).
#
# TD-MPC2's recipe here: MLP latent dynamics (`model.dynamics_type='mlp'`) with its
# LayerNorm + SimNorm (groups of 8) on the encoder's and the dynamics' output
# (`model.latent_norm`); horizon 3; two-hot Q heads (101 symlog bins, cross-entropy;
# `critic.heads`); 5 Q members with its TD target r + gamma min of two random target members at
# (z', a' ~ pi(z')), z' the online encoder's latent (`critic.td_target='tdmpc2'`); its max-Q
# policy with entropy 1e-4 and its tanh log-std map (`critic.actor='maxq'`); its loss weights
# (consistency 20, reward 0.1, Q 0.1) and no teacher-forced dynamics loss (only its latent
# rollout's consistency); its gradient clip 20 and EMA 0.99 (tau 0.01); MPPI with policy
# trajectories (8 of the actor prior, 48 Gaussian samples around the shifted previous plan,
# std 2, 3 rounds of 32 around 8 elites, temperature 0.5, std at least 0.05) while acting and
# evaluating, no optimism, white noise of TD-MPC2's min_std on the executed action. No
# diffusion proposal candidates at all (`plan.num_candidates` = the actor prior's 8,
# `online.act_proposal=False`), and the proposal network is not trained (`loss.w_act=0`).
#
# Deviations from TD-MPC2, each a limit of this library's kinds or of `:cpu`'s budget:
# - Budget: width 64, latent 64 (8 SimNorm groups), Q and policy MLPs (64, 64), batch 128
#   (TD-MPC2 5M: 512, 512, 256); MPPI 56 first-round samples + 3 x 32, 8 elites (TD-MPC2: 512
#   x 6, 24 policy trajectories, 64 elites).
# - The reward comes from this project's sequence objective (a causal transformer over
#   (z_0, a_0, ..., z_H), two-hot, 101 bins; 1 block at width 64), not an MLP of (z, a); it
#   learns on the encoder's latents and the model's rollout (detached), not on the rollout only.
# - The planner's terminal value is a V ensemble (5 two-hot heads) distilled onto the mean of
#   two random target Q members at (z, a ~ pi(z)) (loss weight 0.1), not Q(z_H, pi(z_H))
#   itself; and the Q members learn on the encoder's latents, not the dynamics rollout's.
# - Values are in units of critic.value_scale = 100 (two-hot over symlog of those units), and
#   the max-Q policy loss averages all 5 Q members at that fixed scale: TD-MPC2 averages two
#   random members and divides Q by a running 5-95 percentile scale.
# - No rho^t = 0.5^t weighting of the losses over the horizon (uniform); no encoder learning-
#   rate scale 0.3; no dropout (0.01) in the Q MLPs; the learning rate is warmed up over 100
#   updates; the policy shares the one Adam optimiser.
# - Policy trajectories: the policy's mode plus N(0, 0.2^2) noise (the first the mode alone),
#   while acting and evaluating, standing in for draws of its stochastic policy; the executed
#   sequence is the argmax of J over all candidates (TD-MPC2 draws an elite from the softmax
#   of its scores), with white noise 0.05 on the executed action (TD-MPC2: the last round's
#   std, at least 0.05).
# - Seed steps 1,600 simulator steps (2 waves of 4 episodes; TD-MPC2: 1,000 decisions = 2,000
#   steps), then 800 updates at once, as `:cpu`.
TDMPC2_CPU = {
    'horizon': 3,  # TD-MPC2's planning and training horizon.
    'model.dynamics_type': 'mlp', 'model.latent_norm': 'simnorm',
    'critic.latent_rollout': True,  # TD-MPC2 learns its heads on the latent rollout.
    'critic.num_q': 5, 'critic.num_values': 5, 'critic.heads': 'two_hot',
    'critic.td_target': 'tdmpc2', 'critic.actor': 'maxq', 'critic.log_std_map': 'tanh',
    'critic.entropy_coef': 1e-4,
    # TD-MPC2's coefficients: consistency 20, reward 0.1, value 0.1; no teacher-forced dynamics
    # loss and no proposal (weight 0: left out of the loss).
    'loss.w_dyn': 0.0, 'loss.w_act': 0.0, 'loss.w_val': 0.0, 'loss.w_consistency': 20.0,
    'loss.w_rew': 0.1, 'loss.w_q': 0.1, 'loss.w_v': 0.1, 'loss.w_actor': 1.0,
    'train.grad_clip': 20.0,
    # MPPI with policy trajectories, acting and evaluating alike: the 8 policy trajectories are
    # the only first-round candidates besides the 48 Gaussian ones.
    'plan.num_candidates': 8, 'plan.num_prior_candidates': 8, 'plan.prior_noise_std': 0.2,
    'plan.num_gaussian': 48, 'plan.iterations': 3, 'plan.num_refine': 32, 'plan.num_elites': 8,
    'plan.gaussian_std': 2.0, 'plan.temperature': 0.5, 'plan.min_std': 0.05,
    'plan.pessimism': 0.0, 'plan.selection': 'argmax',
    'online.act_num_gaussian': 48, 'online.act_iterations': 3, 'online.act_proposal': False,
    'online.act_pessimism': 0.0, 'online.action_noise_std': 0.0,
    'online.exec_noise_start': 0.05, 'online.exec_noise_end': 0.05, 'online.exec_noise_corr': 0.0,
    'eval.baselines': ('actor',),
}


PRESETS = ('', 'reference', 'cpu', 'finetune', 'smoke', 'tdmpc2_cpu')
# Presets that were removed or renamed, and what to use; their results stay in docs/results.md,
# and the last commit that has them is e421b33 (big_vision's "last known good commit").
REMOVED = {
    'cpu_tanh': "is now ':cpu'",
    'cpu_optimistic': "was removed (commit e421b33 has it); use ':cpu'",
    'cpu_correlated': "was removed (commit e421b33 has it); use ':cpu'",
    'cpu_v1': "was removed (commit e421b33 has it); use ':cpu'",
}


def get_config(preset: str | None = None) -> ml_collections.ConfigDict:
  if preset in REMOVED:
    raise ValueError(f'preset {preset!r} {REMOVED[preset]}')
  if preset not in (None,) + PRESETS:
    raise ValueError(f"unknown preset {preset!r}: use one of {', '.join(map(repr, PRESETS))}")
  size = {'cpu': 'cpu', 'tdmpc2_cpu': 'cpu', 'finetune': 'cpu', 'smoke': 'smoke'}.get(preset)
  c = door_open.get_config(size)
  c.online = o = online_settings()
  # Observation statistics of random-action seed episodes do not cover the states the agent
  # reaches later (the door barely moves in them): raw observations from scratch, as TD-MPC2.
  c.model.normalize_obs = False
  if preset == 'cpu':
    _cpu(c)
  elif preset == 'tdmpc2_cpu':  # :cpu's budget, TD-MPC2's recipe (TDMPC2_CPU, above).
    _cpu(c)
    c = overrides.with_overrides(c, TDMPC2_CPU)
  elif preset == 'finetune':
    c.model.normalize_obs = True  # The offline checkpoint's networks (its data's statistics).
    o.act_pessimism = c.plan.pessimism  # As measured (docs/results.md): acting as it evaluates.
    o.plan_chunk = 0
    o.update_ratio = 0.1
    o.env_steps = 50_000
    o.seed_steps = 0  # The offline run's data and policy instead of random actions.
  elif preset == 'smoke':
    o.env_steps = 120
    o.num_envs = 2
    o.episode_steps = 20  # 10 decisions at action repeat 2.
    o.seed_steps = 40  # One wave.
    o.update_ratio = 0.1
    o.plan_chunk = 0
    o.checkpoint_every = 40
    o.eval_every = 80
  return c
