"""Errors a user can cause. The CLI prints their message alone and exits non-zero."""


class SigmarlError(Exception):
    """A problem with the user's input (map file, config, checkpoint, tracking store)."""


class MapError(SigmarlError):
    """A map file or map definition that cannot be used; the message names file and element."""


class Terminated(KeyboardInterrupt):
    """SIGTERM (sent by `kill`, `timeout`, SLURM), raised like Ctrl-C: whatever handles an
    interruption (a run ended KILLED, a half-written file removed) handles it too."""


_terminating = False  # set by the SIGTERM handler (cli.handle_sigterm) before it raises


def note_termination() -> None:
    global _terminating
    _terminating = True


def was_interrupted(error: BaseException) -> bool:
    """Whether `error` is, or stands in for, a Ctrl-C or SIGTERM.

    A signal raises at whatever line is running, and a library's cleanup can replace the
    KeyboardInterrupt with its own error (measured: a SIGTERM inside a torchrl module call
    surfaced as tensordict's "Converting a tensordict to boolean value is not permitted", and
    the job was marked failed). So the error's chain is searched, and a SIGTERM received by
    this process counts whatever error it turned into.
    """
    if _terminating:
        return True
    seen, todo = set(), [error]
    while todo:
        e = todo.pop()
        if e is None or id(e) in seen:
            continue
        if isinstance(e, KeyboardInterrupt):
            return True
        seen.add(id(e))
        todo += [e.__cause__, e.__context__]
    return False
