"""Runs ../shared/peers/peer_torch.py, unchanged, inside torch.autocast("cpu", dtype=torch.bfloat16):
PyTorch's own mixed precision (bf16 matrix products through oneDNN), the like-for-like peer for evnerf's
nn::Bf16 networks. Usage: peer_autocast.py PEER [peer flags]. bench/run.sh sets the environment the
peer's best-configuration flags ask for before starting this, so the peer does not re-execute itself
(which would leave the autocast context)."""
import runpy
import sys

import torch

peer = sys.argv[1]
sys.argv = [peer] + sys.argv[2:]
with torch.autocast("cpu", dtype=torch.bfloat16):
    runpy.run_path(peer, run_name="__main__")
