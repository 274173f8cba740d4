#!/usr/bin/env bash
# One device run of the GPU training (docs/training.md, "On a GPU"), prepared on a CPU. Each stage
# has its share of a deadline ($DEADLINE seconds from the start, default 540), so a run cut short still brings back
# what it finished:
#   1. steps per second of the old loop (data from the CPU), the eager loop (data on the GPU) and --graph, with the
#      weights' drift after the same steps (benchmarks/gpu/train_graph.py), and the same of ikdp.distill's one-step
#      recipe, eager against graph (benchmarks/gpu/distill_graph.py);
#   2. a Panda teacher trained by `ikdp.train --device cuda --graph` for the minutes left (without --graph if the
#      graph fails at its start), its solving weights in 15 MB parts (measured afterwards on a CPU, where the
#      benchmark's 1000 held-out targets are);
#   3. the training and distillation steps' and the captured solve's CUDA tests, in the time that remains.
# Everything goes to $OUT. Run from the repository root on the device machine, with .whl (tyro and
# pytorch_kinematics wheels) and .gpu carried: it has no example-robot-data, so the Panda's URDF goes as
# .gpu/example-robot-data/robots/panda_description/urdf/panda.urdf (under that package's own folder names, the
# path the checkpoint records resolves to the installed copy, meshes and all, on the machine that loads it):
#   bash benchmarks/gpu/train_session.sh
# A dry run on a CPU: DEVICE=cpu GRAPH=--no-graph DEADLINE=200 OUT=/tmp/out bash benchmarks/gpu/train_session.sh
set -uo pipefail
DEADLINE=${DEADLINE:-540}
DEVICE=${DEVICE:-cuda}
GRAPH=${GRAPH:---graph}
PANDA=${PANDA_URDF:-.gpu/example-robot-data/robots/panda_description/urdf/panda.urdf}
left() { echo $((DEADLINE - SECONDS)); }
if [ -d .whl ]; then
    python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl
    export PYTHONPATH=/tmp/site:$PWD
fi
export PYTHONUNBUFFERED=1
{ nvidia-smi --query-gpu=name,driver_version --format=csv,noheader; python3 -c "import torch; print(torch.__version__)"; } \
    2>&1 | tee "$OUT/bench.log"

STEPS=50 WINDOWS=3 timeout 100 python3 -m benchmarks.gpu.train_graph "$PANDA" "$DEVICE" 2>&1 | tail -14 \
    | tee -a "$OUT/bench.log"

timeout 120 python3 -m benchmarks.gpu.distill_graph ikdp_panda "$DEVICE" 2>&1 | grep -v "reference pool" | tail -5 \
    | tee -a "$OUT/bench.log"

mkdir -p runs
train() {  # $1: seconds of training; the rest: extra options
    local seconds=$1
    shift
    local minutes
    minutes=$(python3 -c "print(round(max($seconds, 30) / 60, 2))")
    echo "training for $minutes min $*" | tee -a "$OUT/train.log"
    python3 -m ikdp.train --urdf "$PANDA" --ee-link panda_hand --device "$DEVICE" --minutes "$minutes" \
        --save-every 10000 --eval-targets 500 --output runs/panda_gpu.pt "$@" 2>&1 | tr '\r' '\n' \
        | grep -v -E "it/s|s/s," | tee -a "$OUT/train.log" | tail -6
}
started=$SECONDS
train $(($(left) - 150)) $GRAPH
if [ ! -f runs/panda_gpu.pt ] && [ $((SECONDS - started)) -lt 90 ]; then  # the graph failed at its start
    train $(($(left) - 150)) --no-graph
fi

# the solving weights alone (no optimizer state), in parts under the 16 MB a file may bring back
python3 -m ikdp.ship --model runs/panda_gpu.pt --output runs/panda_gpu_slim.pt \
    && split -b 15M -d runs/panda_gpu_slim.pt "$OUT/panda_gpu.pt.part"
tar czf "$OUT/logs.tgz" runs/logs 2>/dev/null

if [ "$(left)" -gt 20 ]; then
    timeout "$(left)" python3 -m pytest -q -p no:cacheprovider tests/test_train_steps.py tests/test_distill_steps.py \
        tests/test_cuda_graph.py 2>&1 | tail -25 | tee "$OUT/tests.log"
fi
echo "done at ${SECONDS}s"
