"""KGN / KGNv2: variants, training targets, network, losses, decoding with IPPE PnP, training."""
