"""The contact gate: does anything touch the gel, and can this frame be judged at all?

``contact_gate`` (ContactGate, GateResult) composes the judging checks (``checks``) over the
one downscaled frame (``reduce``) with its ``options`` (GateOptions); ``learning`` keeps the
background and decides when a mismatched one is re-learnt; ``given_background`` says whether
a background handed to the runtime holds a press.
"""

from __future__ import annotations

from .contact_gate import THUMB_CELL_PX, ContactGate, GateResult
from .options import GateOptions

__all__ = ["THUMB_CELL_PX", "ContactGate", "GateOptions", "GateResult"]
