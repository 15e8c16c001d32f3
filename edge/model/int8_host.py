"""Whether onnxruntime's fused int8 kernels compute a bundle's int8 QDQ graph as written on this host.

On x86-64 without VNNI (AVX2 or AVX-512 without ``avx512_vnni`` / ``avx_vnni``), onnxruntime's fused
uint8 x int8 convolutions add products of neighbouring pairs in 16 bits (``vpmaddubsw``), which
saturate when a pair of weights adds up to more than 128 in magnitude against large activations:
weights that use all 8 bits (|q| > 64) can then give another force than the graph says. Measured
on the 2-core AMD EPYC VM (AVX2, no VNNI): the shipped D bundle read up to 6.4 N (mean 0.9 N)
away from its own graph over 64 virtual contact frames, the default 0.11 N, RGBmod+D 0.35 N. Where
that can happen, :func:`exact_qdq_needed` says so and the model's session runs the graph unfused
(``session.disable_quant_qdq``: every QuantizeLinear / DequantizeLinear as written, float
convolutions), which is what the graph means on any host. Weights of 7 bits (``tactile-force
quantize`` writes them by default, ``--weight-bits 7``) never saturate, and keep the fused kernels
everywhere. Hosts with VNNI and
ARM (``sdot`` / ``udot``) add in 32 bits: nothing to do there.
"""

from __future__ import annotations

import functools
import platform

__all__ = ["exact_qdq_needed", "host_adds_in_16_bits"]

#: the largest |int8 weight| that cannot saturate a 16-bit pair sum against uint8 activations:
#: 255 x (64 + 64) = 32640 <= 32767 (onnxruntime's 7-bit range, ``reduce_range``, is [-64, 64])
SAFE_WEIGHT = 64


@functools.cache
def host_adds_in_16_bits() -> bool:
    """Whether this host's fused uint8 x int8 kernels add pairs in 16 bits: x86-64 without VNNI
    (read from /proc/cpuinfo; an x86 host whose flags cannot be read counts as one)."""
    if platform.machine().lower() not in ("x86_64", "amd64", "i386", "i686", "x86"):
        return False
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as f:
            flags = next((line.split(":", 1)[1].split() for line in f if line.startswith("flags")), [])
    except OSError:
        return True
    return not ({"avx512_vnni", "avx_vnni", "amx_int8"} & set(flags))


def exact_qdq_needed(int8_weight_max: int) -> bool:
    """Whether a graph whose int8 weights reach ``int8_weight_max`` in magnitude must run unfused here
    to give the forces it defines (weights of more than 7 bits on a host that adds in 16 bits)."""
    return int8_weight_max > SAFE_WEIGHT and host_adds_in_16_bits()
