#!/bin/bash
# Trains MT10 seeds 1 and 2 after seed 0 (started by hand with train.sh 0), one at a time, at
# nice 19 so that the evaluations of finished seeds (queue_eval.sh) go first.
until grep -q "seed 0 exit" /work/runs31/train_done.log 2>/dev/null; do sleep 30; done
nice -n 19 /work/runs31/train.sh 1
nice -n 19 /work/runs31/train.sh 2
