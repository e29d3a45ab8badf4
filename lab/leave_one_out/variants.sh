# The leave-one-out variants of door_open_online.py:cpu_tanh: `overrides NAME` prints the flags
# that undo one change (sourced by leave_one_out.sh and resume.sh, so both use the same flags).
# SEED picks the training seed (2 unless set: the seed the one-seed leave-one-out ran on).
SEED=${SEED:-2}
case "$SEED" in *[!0-9]*|'') echo "SEED must be a whole number, got '$SEED'" >&2; return 2 ;; esac
BASE="--config=experiments/configs/door_open_online.py:cpu_tanh --config.seed=$SEED --config.online.plan_chunk=4"
# VARIANTS picks the runs of leave_one_out.sh (the first four by default); overrides knows all seven.
VARIANTS=${VARIANTS:-"no_maxq no_search no_optimism no_exec_noise"}
ALL_VARIANTS="no_maxq no_search no_optimism no_exec_noise no_discount no_episode_shape no_update_ratio"
overrides() {
  case "$1" in
    no_maxq) echo "--config.critic.td_target=window --config.critic.actor=awr" ;;  # IQL values, AWR actor
    no_search) echo "--config.online.act_num_gaussian=0 --config.online.act_iterations=0" ;;
    no_optimism) echo "--config.online.act_pessimism=0.0" ;;
    no_exec_noise) echo "--config.online.exec_noise_start=0.0 --config.online.exec_noise_end=0.0" ;;
    no_discount) echo "--config.gamma=0.99" ;;  # The base config's discount, not TD-MPC2's 0.95 for 100 decisions
    no_episode_shape) echo "--config.online.episode_steps=500" ;;  # Meta-World's 500-step episodes: 200 resets in 100k, not 500
    no_update_ratio) echo "--config.online.update_ratio=0.1" ;;  # The first CPU preset's budget (:cpu_v1), not TD-MPC2's one per decision
    *) echo "unknown variant '$1': use one of $ALL_VARIANTS" >&2; return 2 ;;
  esac
}
