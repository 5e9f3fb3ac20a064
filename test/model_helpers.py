"""Detectors whose batch norms are not the identity, for tests of functions that must hold on trained weights."""

from __future__ import annotations

import torch


def randomise_batch_norms(model: torch.nn.Module) -> torch.nn.Module:
    """Give every batch norm of ``model`` random statistics, scales and shifts (from torch's global generator), as
    trained ones have: a fresh model's are the identity, under which a wrong channel order can go unseen."""
    for m in model.modules():
        if isinstance(m, torch.nn.BatchNorm2d):
            m.running_mean.normal_(0, 0.2)  # type: ignore[union-attr]
            m.running_var.uniform_(0.5, 2.0)  # type: ignore[union-attr]
            m.weight.data.uniform_(0.5, 1.5)
            m.bias.data.normal_(0, 0.1)
    return model
