"""T multilayer perceptrons evaluated as one: stacked weights (T, in, out) and batched matrix products.

Every task's VR function f_i (paper eq. 5) is one member of a `StackedMLP`; the baseline reward r_b is a
`StackedMLP` with one member. Tabular MDPs (no features) use an embedding table as first layer, which is
what a linear layer on one-hot features computes, without materialising the (S, S) one-hot matrix.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import torch
from torch import nn


def fourier_features(features: np.ndarray, *, octaves: int) -> np.ndarray:
    """Each feature column x followed by sin(2^l·π·x) and cos(2^l·π·x) for l = 0 … octaves − 1, float32.

    A ReLU MLP on raw coordinates builds smooth bumps out of many linear pieces and learns them slowly
    ("spectral bias"); sinusoids of the coordinates at a few octaves let it represent hills directly
    (Tancik et al. 2020). ``octaves=0`` returns the features unchanged.
    """
    if octaves == 0:
        return features
    scaled = features[:, :, None] * (np.pi * 2.0 ** np.arange(octaves))  # (S, F, L)
    waves = np.concatenate([np.sin(scaled), np.cos(scaled)], axis=2).reshape(len(features), -1)
    return np.concatenate([features, waves], axis=1).astype(np.float32)


class StackedMLP(nn.Module):
    """``n_members`` independent MLPs ``in → hidden… → 1`` with ReLU, evaluated on shared inputs."""

    def __init__(
        self,
        *,
        n_members: int,
        n_inputs: int,
        hidden: tuple[int, ...],
        tabular: bool,
        generator: torch.Generator,
        input_scale: torch.Tensor | None = None,
    ):
        """``input_scale`` (n_inputs,): factors of each input column's initial first-layer weights (features
        only; `fit.initial_input_scale`); None leaves the default initialisation."""
        super().__init__()
        self.tabular = tabular
        widths = [n_inputs, *hidden, 1]
        self.weights = nn.ParameterList()
        self.biases = nn.ParameterList()
        for layer, (fan_in, fan_out) in enumerate(itertools.pairwise(widths)):
            # nn.Linear's default initialisation U(−1/√fan_in, 1/√fan_in), per member; an embedding row
            # stands for a one-hot input, whose effective fan-in is 1.
            bound = 1.0 / math.sqrt(1 if (tabular and layer == 0) else fan_in)
            w = (torch.rand(n_members, fan_in, fan_out, generator=generator) * 2 - 1) * bound
            if layer == 0 and input_scale is not None:
                w *= input_scale.to(device=w.device, dtype=w.dtype)[None, :, None]
            b = (torch.rand(n_members, 1, fan_out, generator=generator) * 2 - 1) * bound
            self.weights.append(nn.Parameter(w))
            self.biases.append(nn.Parameter(b))

    def forward(self, inputs: torch.Tensor) -> torch.Tensor:
        """Outputs (T, N) for N states: ``inputs`` is (N, F) features, or (N,) state indices when tabular,
        shared by the members; or (T, N, F), (T, N): member t's own N states.

        Tabular indices are gathered with ``index_select``: its backward is a row-wise ``index_add``, several
        times cheaper than advanced indexing's accumulating ``index_put``.
        """
        layers = list(zip(self.weights, self.biases, strict=True))
        w0, b0 = layers[0]
        if not self.tabular:  # the bias as a column of ones: one product yields h and the bias's gradient
            ones = inputs.new_ones(*inputs.shape[:-1], 1)
            h = torch.matmul(torch.cat([inputs, ones], dim=-1), torch.cat([w0, b0], dim=1))
        elif inputs.dim() == 1:
            h = w0.index_select(1, inputs) + b0
        else:  # member t's indices point into its own embedding rows t·S … t·S + S − 1
            n_members, n_states, width = w0.shape
            offsets = torch.arange(0, n_members * n_states, n_states, device=w0.device)[:, None]
            flat = w0.reshape(-1, width).index_select(0, (inputs + offsets).reshape(-1))
            h = flat.reshape(*inputs.shape, width) + b0
        if len(layers) == 1:
            return h.squeeze(-1)
        for w, b in layers[1:-1]:
            h = torch.baddbmm(b, torch.relu_(h), w)  # in place: h is no saved tensor of its producer
        # The last layer has width 1: a product and a sum take half the time of a matrix-vector bmm (and backward).
        w, b = layers[-1]
        return (torch.relu_(h) * w.transpose(1, 2)).sum(dim=-1) + b[:, :, 0]
