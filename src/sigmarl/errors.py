"""Errors a user can cause. The CLI prints their message alone and exits non-zero."""


class SigmarlError(Exception):
    """A problem with the user's input (map file, config, checkpoint, tracking store)."""


class MapError(SigmarlError):
    """A map file or map definition that cannot be used; the message names file and element."""


class Terminated(KeyboardInterrupt):
    """SIGTERM (sent by `kill`, `timeout`, SLURM), raised like Ctrl-C: whatever handles an
    interruption (a run ended KILLED, a half-written file removed) handles it too."""
