"""Traffic environment: a batched VMAS scenario (dynamics, observation, reward, collisions, resets).

`make_env` is imported on first use: `sigmarl.params` (the paper's constants) is read by
code that needs no simulator, and importing VMAS and torchrl costs seconds.
"""

__all__ = ["make_env"]


def __getattr__(name: str):
    if name == "make_env":
        # lazy: importing sigmarl.env costs no VMAS until an environment is made
        from sigmarl.env.factory import make_env

        return make_env
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
