"""Can VGN's rotation head learn the approach from a dataset's labels? Trains the rotation term alone (lr 1e-3,
batches of 4 scenes, the 90° turns) on the scenes with id < SPLIT (default 100) and prints, per epoch, the
training rotation loss and the approach error (median °, share under 20°) on the positives of the scenes with
ids SPLIT to END − 1 (default 171).

    python results/calibration/vgn_rotation_only.py DATASET EPOCHS [SPLIT END]
"""

import sys
from pathlib import Path

import numpy as np
import torch
from torch.utils.data import DataLoader
from vgn_rotation_check import approach_errors  # this folder's script, on the path when run as a script

from kgn_bench.data.vgn_format import read_manifest
from kgn_bench.model.vgn_network import VGNNet
from kgn_bench.training.vgn_train import VGNSceneDataset, collate_scenes, rotation_loss

folder, epochs = Path(sys.argv[1]), int(sys.argv[2])
split, end = (int(sys.argv[3]), int(sys.argv[4])) if len(sys.argv) > 4 else (100, 171)
torch.manual_seed(0)
torch.set_num_threads(1)
manifest = read_manifest(folder)
train = VGNSceneDataset(manifest.folder, [e for e in manifest.scenes if int(e.id) < split], 0, augment=True)
net = VGNNet().use_channels_last()
optimiser = torch.optim.Adam(net.parameters(), 1e-3)


def held_out() -> tuple[float, float]:
    errors, _ = approach_errors(net, folder, split, end)
    return float(np.median(errors)), float(np.mean(errors < 20.0))


for epoch in range(epochs):
    train.set_epoch(epoch)
    total = steps = 0
    for batch in DataLoader(train, batch_size=4, shuffle=True, collate_fn=collate_scenes):
        out = net(batch["tsdf"])
        b, i, j, k = batch["index"].unbind(1)
        positive = batch["label"] > 0.5
        loss = rotation_loss(out.rotation[b, :, i, j, k], batch["quat"])[positive].mean()
        optimiser.zero_grad()
        loss.backward()
        optimiser.step()
        total, steps = total + float(loss.detach()), steps + 1
    median, share = held_out()
    print(f"epoch {epoch + 1}: training rotation loss {total / steps:.4f}; held-out approach error median "
          f"{median:.1f}°, under 20° {100 * share:.0f} %", flush=True)
