"""Waters muscles on the PDE face: model, placement, AUs from activations (the FAS)."""
