"""Checkpoints: one dict per file, written atomically so a crash never leaves half a file.

`checkpoint.pt` is the resume point (kind "resume": policy, critic, optimiser, RNG states;
written before the first iteration and every `ppo.checkpoint_every` iterations). `best.pt`
(the policy with the best mean episode reward) and `final.pt` (after the last iteration) are
small (kind "policy"): the policy's weights and what loading and evaluating it needs
(config, dims, iteration, reward). Any of the three loads with `load_policy`.

Everything read back is validated: a file that is not a checkpoint, lacks a key, or holds
weights that are not finite or whose names or shapes differ from the network its config
builds is one SigmarlError. Each file carries the SHA-256 of what it holds (key "sha256",
format 2; written in the same atomic write, so a kill never parts the two): a flipped bit in
a weight would otherwise load as a plausible number. A format-1 checkpoint was written before
the checksum and loads as it did; one whose content differs from its checksum is refused as
damaged (no older resume point is kept to fall back to).
"""

from __future__ import annotations

import hashlib
import random
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import torch

from sigmarl.config import Config, config_from_dict
from sigmarl.errors import SigmarlError

# the run folder's checkpoint names, read as `ckpt.RESUME_FILE` etc.
from sigmarl.run import BEST_FILE, FINAL_FILE, RESUME_FILE, write_atomic  # noqa: F401

FORMAT = 2  # 2: carries the checksum of its content (CHECKSUM); a bit flip cannot make it 1
LEGACY_FORMAT = 1  # written before the checksum: loads unchecked, as it always did

POLICY_KEYS = ("iteration", "policy", "config", "dims")  # what every checkpoint holds
RESUME_KEYS = (*POLICY_KEYS, "critic", "optimizer", "rng")
TRAINING_ONLY = ("critic", "optimizer", "rng")  # left out of best.pt and final.pt
CHECKSUM = "sha256"  # the digest of everything else the checkpoint holds (`digest`)


def policy_only(state: dict[str, Any]) -> dict[str, Any]:
    """A resume state cut down to what evaluation needs (kind "policy")."""
    return {**{k: v for k, v in state.items() if k not in TRAINING_ONLY}, "kind": "policy"}


def save_atomic(state: dict[str, Any], path: Path) -> None:
    """A checkpoint written whole or not at all (`sigmarl.run.write_atomic`); a failed write (a
    full disk) is one line, and the previous checkpoint is kept."""
    state = {**{k: v for k, v in state.items() if k != CHECKSUM}, "format": FORMAT}
    state[CHECKSUM] = digest(state)
    try:
        write_atomic(path, lambda f: torch.save(state, f))
    except BaseException as e:
        # torch reports a failed write (a full disk) as a RuntimeError around the OSError
        cause = e if isinstance(e, OSError) else e.__context__ if isinstance(e, RuntimeError) else None
        if isinstance(cause, OSError):
            kept = " (the previous one is kept)" if path.exists() else ""
            raise SigmarlError(f"cannot write checkpoint {path}: {cause.strerror or cause}{kept}") from e
        raise


def load(path: Path, device: str | torch.device = "cpu", resume: bool = False) -> dict[str, Any]:
    """Read a checkpoint (with `resume`, one that training can resume from); anything
    unreadable, foreign or incomplete is a one-line SigmarlError (the file is left alone)."""
    path = Path(path)
    if not path.is_file():
        raise SigmarlError(f"no checkpoint at {path}")
    try:
        state = torch.load(path, map_location=device, weights_only=True)
    except Exception as e:  # torch raises many types for truncated or foreign files; its
        # message advises weights_only=False, which would run whatever the file holds
        raise SigmarlError(f"checkpoint {path} is unreadable: truncated, or not a sigmarl "
                           f"checkpoint ({type(e).__name__})") from e
    if not isinstance(state, dict) or state.get("format") not in (LEGACY_FORMAT, FORMAT):
        raise SigmarlError(f"{path} is not a sigmarl checkpoint (format {LEGACY_FORMAT} or {FORMAT})")
    if (state["format"] == FORMAT or CHECKSUM in state) and not _intact(state):
        # no earlier resume point is kept to fall back to: refused, never resumed
        what = "resumed: restore it from a copy, or move the run folder away and train again" if resume \
            else "used: restore it from a copy"
        raise SigmarlError(f"checkpoint {path} is damaged: what it holds differs from the checksum it was "
                           f"saved with (a flipped bit, or an edit); it cannot be {what}")
    kind = state.get("kind", "resume")  # files written before best/final became small
    needed = RESUME_KEYS if resume or kind == "resume" else POLICY_KEYS
    missing = sorted(set(needed) - state.keys())
    if missing:
        what = "resume from" if resume and kind == "policy" else "use"
        raise SigmarlError(f"checkpoint {path} lacks {missing}; cannot {what} it")
    _check_dims(state["dims"], path)
    for key in ("policy", "critic"):
        if key in needed and not _tensor_dict(state[key]):
            raise SigmarlError(f"checkpoint {path}: {key!r} is not a dict of tensors")
        if key in needed and (bad := _not_finite(state[key])):
            # a diverged training's weights: the rollout would fail deep inside the simulator
            raise SigmarlError(f"checkpoint {path}: {key} tensor {bad} holds NaN or infinite values")
    if resume and (bad := _optimiser_not_finite(state["optimizer"])):
        # resuming would take NaN steps: the next best.pt would hold NaN weights
        raise SigmarlError(f"checkpoint {path}: the optimiser state {bad}; it cannot be resumed: move "
                           "the run folder away and train again (its best.pt and final.pt stay usable)")
    if not isinstance(state["config"], dict) or not isinstance(state["iteration"], int):
        raise SigmarlError(f"checkpoint {path}: 'config' or 'iteration' is malformed")
    return state


def _intact(state: dict[str, Any]) -> bool:
    """Whether the content matches the checksum it was saved with (taken out of `state`)."""
    saved = state.pop(CHECKSUM, None)  # a format-2 file without one: its key is damaged
    try:
        return saved == digest(state)
    except Exception:  # content too garbled even to hash (a tensor torch cannot read back)
        return False


def digest(state: Mapping[str, Any]) -> str:
    """SHA-256 of a checkpoint's content but its checksum: every tensor's dtype, shape and bytes
    and every plain value, in an order and form a save/load round trip keeps (dict keys sorted,
    lists and tuples alike, tensors on the CPU)."""
    h = hashlib.sha256()

    def feed(x: Any) -> None:
        if isinstance(x, torch.Tensor):
            flat = torch.empty(x.numel(), dtype=x.dtype).copy_(x.detach().reshape(-1))  # dense, stride 1
            h.update(f"T{x.dtype}{tuple(x.shape)}:".encode())
            h.update(flat.view(torch.uint8).numpy().tobytes())
        elif isinstance(x, Mapping):
            h.update(b"{")
            for key in sorted(x, key=repr):
                feed(key)
                feed(x[key])
            feed(getattr(x, "_metadata", None))  # a state_dict's versions, which loading it reads
            h.update(b"}")
        elif isinstance(x, list | tuple):  # random.getstate's tuples may come back as lists
            h.update(b"[")
            for item in x:
                feed(item)
            h.update(b"]")
        else:  # str, int, float, bool, None: their repr reads back the same
            h.update(f"{type(x).__name__}:{x!r};".encode())

    feed({k: v for k, v in state.items() if k != CHECKSUM})
    return h.hexdigest()


def config_of(state: dict[str, Any], path: Path) -> Config:
    """The training config a loaded checkpoint holds (kept in it as a plain dict)."""
    return config_from_dict(state["config"], f"checkpoint {path}: its config")


def _tensor_dict(d: Any) -> bool:
    return isinstance(d, Mapping) and all(isinstance(v, torch.Tensor) for v in d.values())


def _not_finite(weights: Mapping[str, torch.Tensor]) -> str | None:
    """The name of the first floating-point tensor with a NaN or an infinity, if any."""
    return next((k for k, t in weights.items() if t.is_floating_point() and not torch.isfinite(t).all()), None)


def _optimiser_not_finite(optimiser: Any) -> str | None:
    """What in an optimiser's state_dict is malformed or not finite (a NaN moment, a NaN lr), if any."""
    if not isinstance(optimiser, Mapping) or not isinstance(optimiser.get("state"), Mapping) \
            or not isinstance(optimiser.get("param_groups"), list):
        return "is malformed (not an optimiser's state_dict)"
    for index, slots in optimiser["state"].items():
        if not isinstance(slots, Mapping):
            return f"of parameter {index} is malformed"
        for name, value in slots.items():
            if isinstance(value, torch.Tensor) and value.is_floating_point() and not torch.isfinite(value).all():
                return f"of parameter {index} holds NaN or infinite values in {name!r}"
    for group in optimiser["param_groups"]:
        for name, value in (group.items() if isinstance(group, Mapping) else []):
            if isinstance(value, float) and not np.isfinite(value):
                return f"sets {name} to {value}"
    return None


def _check_dims(dims: Any, path: Path) -> None:
    ok = (
        isinstance(dims, dict)
        and all(isinstance(dims.get(k), int) and dims[k] > 0 for k in ("obs_dim", "n_agents"))
        and all(isinstance(dims.get(k), torch.Tensor) and dims[k].dim() == 1
                and dims[k].numel() > 0 for k in ("action_low", "action_high"))
        and dims["action_low"].shape == dims["action_high"].shape
    )
    if not ok:
        raise SigmarlError(f"checkpoint {path}: 'dims' is malformed (needs positive ints obs_dim, "
                           "n_agents and equal-length 1-d tensors action_low, action_high)")


def check_weights(found: Mapping[str, torch.Tensor], network: torch.nn.Module, what: str,
                  path: Path) -> None:
    """The checkpoint's tensors must be exactly the network's: same names, same shapes."""
    expected = network.state_dict()
    missing = sorted(expected.keys() - found.keys())
    extra = sorted(found.keys() - expected.keys())
    if missing or extra:
        parts = [f"missing {missing[:3]}" if missing else "", f"unexpected {extra[:3]}" if extra else ""]
        raise SigmarlError(f"checkpoint {path}: the {what} weights do not fit the network its "
                           f"config builds ({'; '.join(p for p in parts if p)})")
    for key, tensor in expected.items():
        if tuple(found[key].shape) != tuple(tensor.shape):
            raise SigmarlError(f"checkpoint {path}: {what} tensor {key} has shape "
                               f"{tuple(found[key].shape)}, the network's is {tuple(tensor.shape)}")


def rng_state() -> dict[str, Any]:
    """Every global generator the training touches (torch CPU/CUDA, numpy, random)."""
    np_state = np.random.get_state()
    state: dict[str, Any] = {
        "torch": torch.get_rng_state(),
        "numpy": [np_state[0], torch.from_numpy(np_state[1].copy()), *np_state[2:]],
        "random": random.getstate(),
    }
    if torch.cuda.is_available() and torch.cuda.is_initialized():
        state["cuda"] = torch.cuda.get_rng_state_all()
    return state


def set_rng_state(state: dict[str, Any]) -> None:
    torch.set_rng_state(state["torch"].cpu())
    name, keys, *rest = state["numpy"]
    np.random.set_state((name, keys.cpu().numpy(), *rest))
    random.setstate(_as_tuple(state["random"]))
    if "cuda" in state and torch.cuda.is_available():
        torch.cuda.set_rng_state_all([s.cpu() for s in state["cuda"]])


def _as_tuple(x: Any) -> Any:
    """random.setstate wants nested tuples; a save/load round trip may turn them into lists."""
    return tuple(_as_tuple(v) for v in x) if isinstance(x, list | tuple) else x
