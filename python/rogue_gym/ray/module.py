"""An RLlib ``RLModule`` holding the paper's networks, fed the pool's uint8 observations.

RLlib's default catalog reads image observations as ``[H, W, C]`` floats, so it finds no CNN for
the pool's ``[C, H, W]`` uint8 screens and its torch convolutions reject uint8. This module
takes them as they come off the wire and converts them on the learner's device:

* ``symbol_index`` screens ``(H, W)``: the networks of :mod:`rogue_gym.train.networks`
  (one-hot by table lookup, no float input at all); ``small``, ``large`` or ``batchnorm``.
* channel-first planes ``(C, H, W)`` (``symbol_onehot``, with any status or history planes):
  the ``small`` network with a dense first convolution over the planes cast to float32.

``model_config={"variant": "small"}`` (the default) picks the network. The ``l2`` and VAE
variants need their own optimizer or loss and live in ``python -m rogue_gym.train`` only.
"""

from __future__ import annotations

from typing import Any, Optional

import torch
from ray.rllib.core.columns import Columns
from ray.rllib.core.rl_module.apis.value_function_api import ValueFunctionAPI
from ray.rllib.core.rl_module.torch import TorchRLModule
from torch import nn

from ..train.networks import RELU_GAIN, PolicyNet, SmallNet, build_network, orthogonal_init

__all__ = ["RLLIB_VARIANTS", "RogueRLModule"]

#: The variants this module builds (``model_config["variant"]``).
RLLIB_VARIANTS = ("small", "large", "batchnorm")


class PlanesSmallNet(SmallNet):
    """PPO Small over channel-first planes: a dense first convolution on the float32 cast."""

    def __init__(self, channels: int, height: int, width: int, num_actions: int) -> None:
        super().__init__(channels, height, width, num_actions)
        self.conv1 = orthogonal_init(nn.Conv2d(channels, 32, 8), RELU_GAIN)

    def body(self, x: torch.Tensor) -> torch.Tensor:
        """The Small network's features of ``(B, C, H, W)`` planes of any dtype."""
        return super().body(x.float())


def _network(obs_space: Any, num_actions: int, variant: str) -> PolicyNet:
    if variant not in RLLIB_VARIANTS:
        raise ValueError(
            f"model_config['variant'] must be one of {RLLIB_VARIANTS} under RLlib, got "
            f"{variant!r} (l2 and the VAEs need python -m rogue_gym.train)"
        )
    shape = tuple(obs_space.shape)
    if len(shape) == 2:
        symbols = int(obs_space.high.max()) + 1
        return build_network(variant, symbols, shape[0], shape[1], num_actions)
    if len(shape) == 3:
        if variant != "small":
            raise ValueError(
                f"the {variant!r} network reads symbol_index screens: pass obs='symbol_index' "
                "to the pool (configure_rllib(..., obs='symbol_index'))"
            )
        return PlanesSmallNet(shape[0], shape[1], shape[2], num_actions)
    raise ValueError(
        f"RogueRLModule takes (H, W) symbol-index or (C, H, W) observations, got shape {shape}"
    )


class RogueRLModule(TorchRLModule, ValueFunctionAPI):
    """PPO's policy and value function as one of the paper's networks (shared body)."""

    def setup(self) -> None:
        """Build the network for the observation and action spaces."""
        variant = str((self.model_config or {}).get("variant", "small"))
        self.net = _network(self.observation_space, int(self.action_space.n), variant)

    def _forward(self, batch: dict[str, Any], **kwargs: Any) -> dict[str, Any]:
        return {Columns.ACTION_DIST_INPUTS: self.net(batch[Columns.OBS]).logits}

    def _forward_train(self, batch: dict[str, Any], **kwargs: Any) -> dict[str, Any]:
        h = self.net.body(batch[Columns.OBS])
        return {Columns.ACTION_DIST_INPUTS: self.net.policy_head(h), Columns.EMBEDDINGS: h}

    def compute_values(
        self, batch: dict[str, Any], embeddings: Optional[Any] = None
    ) -> torch.Tensor:
        """State values; reuses the train pass's features when given."""
        if embeddings is None:
            embeddings = self.net.body(batch[Columns.OBS])
        return self.net.value_head(embeddings).squeeze(-1)
