"""KGN / KGNv2: variants, training targets, network, losses, decoding with IPPE PnP, checkpoints (torch, no
MuJoCo, no dataset code; training them is ``kgn_bench.training``)."""
