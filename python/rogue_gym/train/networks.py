"""The paper's six policy networks, reading symbol-index screens.

Every network takes a batch of screens as symbol indices, ``(B, H, W)`` integers in
``[0, symbols)`` (uint8 on the wire), and returns :class:`PolicyOutput`: action logits, the
state value and, for the VAE variants, the auxiliary loss.

The paper's networks read the one-hot encoding of the screen (one channel per symbol). A
convolution over a one-hot input is a table lookup: output ``o`` at ``(i, j)`` is the bias plus
the sum, over the kernel's taps ``(dy, dx)``, of the weight ``W[o, symbol(i+dy, j+dx), dy, dx]``.
:class:`OneHotConv2d` computes exactly that with ``embedding_bag`` instead of a dense
convolution over 17 mostly-zero channels. Its parameters have ``Conv2d``'s shapes and meaning,
so the networks are the paper's; only the arithmetic is cheaper (about 30x fewer operations in
the Small network's first layer), and nothing float32 ever crosses the wire.

Variants (``VARIANTS``), after ``../shared/reference/python-api-and-paper-protocol.md`` §3.4:

* ``small``: three valid convolutions (k8, k4, k3; 32, 64, 32 channels), FC 256.
* ``large``: the IMPALA ResNet, channels 16/32/32, 15 convolutions, FC 256.
* ``batchnorm``: ``large`` with batch normalization after every convolution.
* ``l2``: ``large``; the trainer adds weight decay (L2) to the optimizer.
* ``vae`` / ``betavae``: a convolutional VAE encoder whose mean ``mu`` feeds the policy and value
  heads, with a decoder trained jointly (reconstruction + beta * KL; beta 0 and 4).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Optional, Tuple

import torch
import torch.nn.functional as F
from torch import nn

__all__ = [
    "RELU_GAIN",
    "VARIANTS",
    "ImpalaNet",
    "MapLinear",
    "OneHotConv2d",
    "PolicyNet",
    "PolicyOutput",
    "SmallNet",
    "VaeNet",
    "build_network",
    "orthogonal_init",
]

#: The network variants, as ``--variant`` names them.
VARIANTS: Tuple[str, ...] = ("small", "large", "batchnorm", "l2", "vae", "betavae")

#: beta of the KL term for the VAE variants.
VAE_BETA = {"vae": 0.0, "betavae": 4.0}


@dataclass
class PolicyOutput:
    """What a network returns for a batch of screens."""

    logits: torch.Tensor
    """``(B, actions)`` unnormalized action log-probabilities."""
    value: torch.Tensor
    """``(B,)`` state values."""
    aux_loss: Optional[torch.Tensor] = None
    """A scalar loss to add to PPO's (the VAE's), when asked for and the network has one."""


def orthogonal_init(module: nn.Module, gain: float) -> nn.Module:
    """Orthogonal weights with ``gain`` and zero biases (the paper's initializer)."""
    weight = getattr(module, "weight", None)
    if isinstance(weight, torch.Tensor):
        nn.init.orthogonal_(weight, gain)
    bias = getattr(module, "bias", None)
    if isinstance(bias, torch.Tensor):
        nn.init.zeros_(bias)
    return module


#: The orthogonal initializer's gain before a ReLU.
RELU_GAIN = math.sqrt(2.0)


class OneHotConv2d(nn.Module):
    """``Conv2d`` over the one-hot encoding of a symbol-index map, computed by table lookup.

    ``forward(x)`` takes ``(B, H, W)`` integer symbols in ``[0, num_symbols)`` and returns
    ``(B, out_channels, H', W')``, equal (up to float summation order) to
    ``conv2d(one_hot(x).permute(0, 3, 1, 2), weight, bias, padding=padding)``. Zero padding of
    a one-hot input is a cell with no symbol: it indexes a zero row. Stride 1 only.
    """

    def __init__(
        self,
        num_symbols: int,
        out_channels: int,
        kernel_size: int,
        padding: int = 0,
        bias: bool = True,
    ) -> None:
        super().__init__()
        self.num_symbols = num_symbols
        self.kernel_size = kernel_size
        self.padding = padding
        self.weight = nn.Parameter(torch.empty(out_channels, num_symbols, kernel_size, kernel_size))
        self.bias = nn.Parameter(torch.zeros(out_channels)) if bias else None
        nn.init.kaiming_uniform_(self.weight, a=math.sqrt(5))
        # Row offset of each tap (dy, dx) in the lookup table (one extra row per tap: padding).
        taps = torch.arange(kernel_size * kernel_size, dtype=torch.int32) * (num_symbols + 1)
        self.register_buffer("tap_offset", taps.view(kernel_size, kernel_size), persistent=False)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """Convolve the one-hot encoding of ``x`` (``(B, H, W)`` integer symbols)."""
        return _OneHotConv.apply(x, self.weight, self.bias, self.tap_offset, self.padding)


class _OneHotConv(torch.autograd.Function):
    """Forward by table lookup (``embedding_bag``); the weight gradient by lookups too.

    The weight gradient of table row (tap ``(dy, dx)``, symbol ``s``) is the sum of the output
    gradient over the positions whose tap reads ``s``. ``embedding_bag``'s own backward gets
    there by sorting all ``B * H' * W' * k * k`` indices, about 10x slower on a CPU than the
    dense weight-gradient kernel over the one-hot input, which in turn does ``symbols`` times
    the work. Here the gradient is gathered from the cells instead, leaving out the most
    frequent symbol (the blank, about 90% of cells): each other cell, with each tap, names the
    one output position it feeds; grouped by (tap, symbol), these positions are bags for
    ``embedding_bag`` over the output gradient. The one-hot channels, padding included, sum to
    1 in every cell, so the most frequent symbol's gradient is the gradient's total minus the
    others'. Exact up to float summation order, and about 5x faster than the dense kernel.
    """

    @staticmethod
    def forward(
        ctx: Any,
        x: torch.Tensor,
        weight: torch.Tensor,
        bias: Optional[torch.Tensor],
        tap_offset: torch.Tensor,
        padding: int,
    ) -> torch.Tensor:
        out_c, c, k, _ = weight.shape
        # int32 throughout: building the bags in int64 costs several times more on a CPU.
        idx = x.to(torch.int32)
        if padding:
            idx = F.pad(idx, (padding,) * 4, value=c)  # symbol ``c``: the zero row
        b, h, w = idx.shape
        ho, wo = h - k + 1, w - k + 1
        bags = idx.unfold(1, k, 1).unfold(2, k, 1).contiguous()  # (B, Ho, Wo, k, k)
        bags += tap_offset
        bags = bags.view(b * ho * wo, k * k)
        table = F.pad(weight.permute(2, 3, 1, 0), (0, 0, 0, 1))  # (k, k, c + 1, out)
        if bias is not None:
            table[0, 0] += bias  # every position reads exactly one row of tap (0, 0)
        y = F.embedding_bag(bags, table.reshape(-1, out_c), mode="sum")
        ctx.save_for_backward(idx)
        ctx.weight_shape = weight.shape
        return y.view(b, ho, wo, out_c).permute(0, 3, 1, 2)  # NCHW view of NHWC memory

    @staticmethod
    def backward(ctx: Any, grad_out: torch.Tensor) -> Any:
        (idx,) = ctx.saved_tensors
        out_c, c, k, _ = ctx.weight_shape
        b, h, w = idx.shape
        ho, wo = h - k + 1, w - k + 1
        grad = grad_out.permute(0, 2, 3, 1).reshape(b * ho * wo, out_c)  # a view if NHWC
        flat = idx.flatten()
        counts = torch.bincount(flat, minlength=c + 1)  # symbol c: padding
        major = int(torch.argmax(counts))
        # The other cells, grouped by symbol, and their coordinates.
        cells = torch.nonzero(flat != major).squeeze(1)
        _, order = torch.sort(flat[cells], stable=True)
        cells = cells[order]
        cb = cells // (h * w)
        cy = (cells // w) % h
        cx = cells % w
        # Tap (dy, dx) of the cell at (y, x) feeds output (y - dy, x - dx), if that exists.
        taps = torch.arange(k, device=idx.device)
        oy = cy.view(1, 1, -1) - taps.view(k, 1, 1)
        ox = cx.view(1, 1, -1) - taps.view(1, k, 1)
        feeds = (oy >= 0) & (oy < ho) & (ox >= 0) & (ox < wo)  # (k, k, cells)
        pos = torch.where(feeds, (cb.view(1, 1, -1) * ho + oy) * wo + ox, 0)
        # Bags in (tap, symbol) order: each tap's row lists the cells sorted by symbol.
        counts[major] = 0
        starts = torch.cumsum(counts, 0) - counts
        tap_index = torch.arange(k * k, device=idx.device).view(-1, 1)
        offsets = (tap_index * cells.numel() + starts).flatten()
        part = F.embedding_bag(
            pos.flatten(),
            grad,
            offsets,
            mode="sum",
            per_sample_weights=feeds.flatten().to(grad.dtype),
        ).view(k, k, c + 1, out_c)
        total = grad.sum(0)  # the bias's gradient
        part[:, :, major] = total - part.sum(2)
        grad_w = part[:, :, :c].permute(3, 2, 0, 1).contiguous()
        return None, grad_w, total if ctx.needs_input_grad[2] else None, None, None


class MapLinear(nn.Linear):
    """``nn.Linear`` over a flattened feature map, called with the map itself.

    Its parameters and result are ``linear(h.flatten(1), weight, bias)``'s (up to float
    summation order), so the paper's shapes and the checkpoints are unchanged. On a CPU the
    forward and the input gradient run as convolutions (one kernel covering the map; a 1-wide
    kernel over the flattened features), which oneDNN computes in about 60% of the BLAS
    matmul's time on the machines measured, reading a channels-last map without a copy. The
    weight gradient stays a matmul.
    """

    def forward(self, h: torch.Tensor) -> torch.Tensor:
        """``(B, C, H, W)`` -> ``(B, out_features)``."""
        if h.device.type != "cpu":
            return F.linear(h.flatten(1), self.weight, self.bias)
        return _MapLinear.apply(h, self.weight, self.bias)


class _MapLinear(torch.autograd.Function):
    """:class:`MapLinear` on a CPU: convolutions for the forward and the input gradient."""

    @staticmethod
    def forward(
        ctx: Any, h: torch.Tensor, weight: torch.Tensor, bias: Optional[torch.Tensor]
    ) -> Any:
        ctx.save_for_backward(h, weight)
        return F.conv2d(h, weight.view(weight.shape[0], *h.shape[1:]), bias).flatten(1)

    @staticmethod
    def backward(ctx: Any, grad: torch.Tensor) -> Any:
        h, weight = ctx.saved_tensors
        need_h, need_w, need_b = ctx.needs_input_grad
        (b, out), n = grad.shape, weight.shape[1]
        # grad @ weight: the weight as a 1 x n "image" of ``out`` channels, the grad as kernels.
        grad_h = (
            F.conv1d(weight.view(1, out, n), grad.reshape(b, out, 1)).view(h.shape)
            if need_h
            else None
        )
        grad_w = grad.t() @ h.flatten(1) if need_w else None
        return grad_h, grad_w, grad.sum(0) if need_b else None


class PolicyNet(nn.Module):
    """A body producing features, plus the policy and value heads.

    ``original`` (``--compat original``) initialises as the paper's code did where it differs
    from the paper's description (docs/training.md): the value head orthogonal with gain
    sqrt(2) instead of 1, and in the subclasses no residual biases and the VAE's heads and
    decoder orthogonal with gain sqrt(2).
    """

    def __init__(self, features: int, num_actions: int, original: bool = False) -> None:
        super().__init__()
        self.original = original
        self.policy_head = orthogonal_init(nn.Linear(features, num_actions), 0.01)
        self.value_head = orthogonal_init(nn.Linear(features, 1), RELU_GAIN if original else 1.0)

    def body(self, x: torch.Tensor) -> torch.Tensor:
        """Features of a batch of symbol-index screens."""
        raise NotImplementedError

    def forward(self, x: torch.Tensor, with_aux: bool = False) -> PolicyOutput:
        """Logits and values of ``x``; ``with_aux`` is ignored (no auxiliary loss)."""
        h = self.body(x)
        return PolicyOutput(self.policy_head(h), self.value_head(h).squeeze(-1))


class SmallNet(PolicyNet):
    """PPO Small: the DQN-like three-convolution network (valid convolutions, stride 1)."""

    def __init__(
        self, symbols: int, height: int, width: int, num_actions: int, original: bool = False
    ) -> None:
        super().__init__(256, num_actions, original)
        self.conv1: nn.Module = OneHotConv2d(symbols, 32, 8)
        self.conv2 = nn.Conv2d(32, 64, 4)
        self.conv3 = nn.Conv2d(64, 32, 3)
        flat = 32 * (height - 12) * (width - 12)
        self.fc = MapLinear(flat, 256)
        for m in (self.conv1, self.conv2, self.conv3, self.fc):
            orthogonal_init(m, RELU_GAIN)

    def body(self, x: torch.Tensor) -> torch.Tensor:
        """Three ReLU convolutions and a ReLU FC layer."""
        h = F.relu(self.conv1(x))
        h = F.relu(self.conv2(h))
        h = F.relu(self.conv3(h))
        return F.relu(self.fc(h))


class _Residual(nn.Module):
    """ReLU, conv3x3, [BN], ReLU, conv3x3, [BN], plus the skip.

    As in the paper's code, whose first ReLU is in place, the skip carries ``relu(x)``. The
    convolutions have biases unless a BatchNorm follows them or ``bias`` is false (the paper's
    code has none).
    """

    def __init__(self, channels: int, batch_norm: bool, bias: bool = True) -> None:
        super().__init__()
        bias = bias and not batch_norm
        self.conv1 = nn.Conv2d(channels, channels, 3, padding=1, bias=bias)
        self.conv2 = nn.Conv2d(channels, channels, 3, padding=1, bias=bias)
        self.bn1 = nn.BatchNorm2d(channels) if batch_norm else nn.Identity()
        self.bn2 = nn.BatchNorm2d(channels) if batch_norm else nn.Identity()

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """The block's output."""
        x = F.relu(x)
        h = self.bn1(self.conv1(x))
        h = self.bn2(self.conv2(F.relu(h)))
        return x + h


class ImpalaNet(PolicyNet):
    """PPO Large: the IMPALA ResNet (3 stages of conv, max-pool and 2 residual blocks).

    The first stage's pool halves the screen (k3 s2 p1); the later ones keep it (k3 s1 p1), as
    in the paper's code. ``batch_norm`` puts a BatchNorm after every convolution.
    """

    CHANNELS = (16, 32, 32)

    def __init__(
        self,
        symbols: int,
        height: int,
        width: int,
        num_actions: int,
        batch_norm: bool = False,
        original: bool = False,
    ) -> None:
        super().__init__(256, num_actions, original)
        stages = []
        in_c = symbols
        for s, out_c in enumerate(self.CHANNELS):
            conv: nn.Module
            if s == 0:
                conv = OneHotConv2d(symbols, out_c, 3, padding=1, bias=False)
            else:
                conv = nn.Conv2d(in_c, out_c, 3, padding=1, bias=False)
            stride = 2 if s == 0 else 1
            stages.append(
                nn.Sequential(
                    conv,
                    nn.BatchNorm2d(out_c) if batch_norm else nn.Identity(),
                    nn.MaxPool2d(3, stride=stride, padding=1),
                    _Residual(out_c, batch_norm, bias=not original),
                    _Residual(out_c, batch_norm, bias=not original),
                )
            )
            in_c = out_c
        self.stages = nn.Sequential(*stages)
        h, w = (height + 1) // 2, (width + 1) // 2
        self.fc = MapLinear(in_c * h * w, 256)
        for m in self.stages.modules():
            if isinstance(m, (nn.Conv2d, OneHotConv2d)):
                orthogonal_init(m, RELU_GAIN)

    def body(self, x: torch.Tensor) -> torch.Tensor:
        """The ResNet, a ReLU, and a ReLU FC layer."""
        h = F.relu(self.stages(x))
        return F.relu(self.fc(h))


class VaeNet(PolicyNet):
    """(beta-)VAE PPO: the policy and value read the encoder's mean ``mu``.

    Encoder: convolutions k8/k4/k3 with padding 1 (32, 64, 32 channels), FC 256, then ``mu``
    and ``logvar`` (``z_dim`` 64). Decoder: FC 256, FC back to the conv shape, and transposed
    convolutions mirroring the encoder, giving per-cell logits over the symbols. Auxiliary loss:
    per-cell cross-entropy against the screen plus ``beta`` times the KL divergence, each summed
    over a sample and averaged over the batch.
    """

    def __init__(
        self,
        symbols: int,
        height: int,
        width: int,
        num_actions: int,
        beta: float,
        z_dim: int = 64,
        original: bool = False,
    ) -> None:
        super().__init__(z_dim, num_actions, original)
        self.beta = beta
        self.conv1 = OneHotConv2d(symbols, 32, 8, padding=1)
        self.conv2 = nn.Conv2d(32, 64, 4, padding=1)
        self.conv3 = nn.Conv2d(64, 32, 3, padding=1)
        # k8 p1 shrinks by 5, k4 p1 by 1, k3 p1 keeps the size: 16x32 -> 10x26.
        self.conv_shape = (32, height - 6, width - 6)
        flat = self.conv_shape[0] * self.conv_shape[1] * self.conv_shape[2]
        self.fc = MapLinear(flat, 256)
        self.mu = nn.Linear(256, z_dim)
        self.logvar = nn.Linear(256, z_dim)
        self.dec_fc1 = nn.Linear(z_dim, 256)
        self.dec_fc2 = nn.Linear(256, flat)
        self.deconv3 = nn.ConvTranspose2d(32, 64, 3, padding=1)
        self.deconv2 = nn.ConvTranspose2d(64, 32, 4, padding=1)
        self.deconv1 = nn.ConvTranspose2d(32, symbols, 8, padding=1)
        initialised: Tuple[nn.Module, ...] = (self.conv1, self.conv2, self.conv3, self.fc)
        if original:  # the paper's code: its ReLU initializer on every layer but the actor
            initialised += (self.mu, self.logvar, self.dec_fc1, self.dec_fc2)
            initialised += (self.deconv3, self.deconv2, self.deconv1)
        for m in initialised:
            orthogonal_init(m, RELU_GAIN)

    def encode(self, x: torch.Tensor) -> Tuple[torch.Tensor, torch.Tensor]:
        """``(mu, logvar)`` of a batch of screens."""
        h = F.relu(self.conv1(x))
        h = F.relu(self.conv2(h))
        h = F.relu(self.conv3(h))
        h = F.relu(self.fc(h))
        return self.mu(h), self.logvar(h)

    def decode(self, z: torch.Tensor) -> torch.Tensor:
        """Per-cell symbol logits ``(B, symbols, H, W)`` of latent codes ``z``."""
        h = F.relu(self.dec_fc1(z))
        h = F.relu(self.dec_fc2(h)).view(-1, *self.conv_shape)
        h = F.relu(self.deconv3(h))
        h = F.relu(self.deconv2(h))
        return self.deconv1(h)

    def forward(self, x: torch.Tensor, with_aux: bool = False) -> PolicyOutput:
        """Logits and values from ``mu``; with ``with_aux``, the VAE loss of ``x`` too."""
        mu, logvar = self.encode(x)
        out = PolicyOutput(self.policy_head(mu), self.value_head(mu).squeeze(-1))
        if with_aux:
            # The reparameterization noise comes from torch's global RNG (seeded by the trainer).
            z = mu + torch.randn_like(mu) * torch.exp(0.5 * logvar)
            recon = F.cross_entropy(self.decode(z), x.long(), reduction="sum")
            kl = -0.5 * torch.sum(1.0 + logvar - mu.pow(2) - logvar.exp())
            out.aux_loss = (recon + self.beta * kl) / x.shape[0]
        return out


def build_network(
    variant: str, symbols: int, height: int, width: int, num_actions: int, original: bool = False
) -> PolicyNet:
    """The network of ``variant`` (one of :data:`VARIANTS`) for screens of ``height x width``;
    ``original``: initialised as the paper's code (``--compat original``)."""
    if variant == "small":
        return SmallNet(symbols, height, width, num_actions, original=original)
    if variant in ("large", "l2"):
        return ImpalaNet(symbols, height, width, num_actions, original=original)
    if variant == "batchnorm":
        return ImpalaNet(symbols, height, width, num_actions, batch_norm=True, original=original)
    if variant in VAE_BETA:
        return VaeNet(
            symbols, height, width, num_actions, beta=VAE_BETA[variant], original=original
        )
    raise ValueError(f"unknown variant {variant!r}; choose one of {', '.join(VARIANTS)}")
