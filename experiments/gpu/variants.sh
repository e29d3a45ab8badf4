# The leave-one-out variants of door_open_online.py:cpu_tanh: `overrides NAME` prints the flags
# that undo one change (sourced by leave_one_out.sh and resume.sh, so both use the same flags).
# SEED picks the training seed (2 unless set: the seed the one-seed leave-one-out ran on).
SEED=${SEED:-2}
case "$SEED" in *[!0-9]*|'') echo "SEED must be a whole number, got '$SEED'" >&2; return 2 ;; esac
BASE="--config=experiments/configs/door_open_online.py:cpu_tanh --config.seed=$SEED --config.online.plan_chunk=4"
VARIANTS="no_maxq no_search no_optimism no_exec_noise"
overrides() {
  case "$1" in
    no_maxq) echo "--config.critic.td_target=window --config.critic.actor=awr" ;;  # IQL values, AWR actor
    no_search) echo "--config.online.act_num_gaussian=0 --config.online.act_iterations=0" ;;
    no_optimism) echo "--config.online.act_pessimism=0.0" ;;
    no_exec_noise) echo "--config.online.exec_noise_start=0.0 --config.online.exec_noise_end=0.0" ;;
    *) echo "unknown variant '$1': use one of $VARIANTS" >&2; return 2 ;;
  esac
}
