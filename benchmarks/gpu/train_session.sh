#!/usr/bin/env bash
# One device run for issue 27's GPU training (docs/ROBOTS.md, "Training on a GPU"), prepared on a CPU:
#   1. the training step's CUDA tests (a recorded step against eager ones, a --graph run saved and resumed) and the
#      captured solve's;
#   2. steps per second of the old loop (data from the CPU), the eager loop (data on the GPU) and --graph;
#   3. a Panda teacher trained by `ikdp.train --device cuda --graph --minutes $MINUTES`, its raw accuracy (DDPM,
#      K = 1) on robot_benchmark's 1000 held-out targets, its solving weights in 15 MB parts and its TensorBoard logs.
# Everything goes to $OUT. Run from the repository root on the device machine, with .whl (tyro and
# pytorch_kinematics wheels) and .gpu/panda.urdf carried (it has no example-robot-data):
#   MINUTES=4 bash benchmarks/gpu/train_session.sh
set -uo pipefail
python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl
export PYTHONPATH=/tmp/site:$PWD
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader | tee "$OUT/gpu.txt"
python3 -m pytest -q --noconftest -p no:cacheprovider tests/test_train_steps.py tests/test_cuda_graph.py 2>&1 \
    | tail -20 | tee "$OUT/tests.log"
python3 -m benchmarks.gpu.train_graph .gpu/panda.urdf 2>&1 | tail -12 | tee "$OUT/bench.log"
mkdir -p runs
python3 -m ikdp.train --urdf .gpu/panda.urdf --ee-link panda_hand --device cuda --graph --minutes "${MINUTES:-4}" \
    --save-every 2000 --eval-targets 500 --output runs/panda_graph.pt 2>&1 | tr '\r' '\n' | grep -v "it/s" \
    | tail -8 | tee "$OUT/train.log"
python3 -m benchmarks.robot_benchmark --checkpoint runs/panda_graph.pt --raw-only --samplers ddpm \
    --output "$OUT/panda_graph_raw.json" 2>&1 | tail -8 | tee "$OUT/raw.log"
# the solving weights alone (no optimizer state), in parts under the 16 MB a file may bring back
python3 -c "
from pathlib import Path; from ikdp.checkpoint import read_checkpoint, save_checkpoint
payload = read_checkpoint(Path('runs/panda_graph.pt'))
keep = ('model', 'prior', 'train', 'metrics', 'history', 'state_dict')
save_checkpoint(Path('runs/panda_graph_slim.pt'), {key: payload[key] for key in keep})"
split -b 15M -d runs/panda_graph_slim.pt "$OUT/panda_graph.pt.part"
tar czf "$OUT/logs.tgz" runs/logs
