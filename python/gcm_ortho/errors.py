"""The exceptions a run raises, one class a kind of problem.

Each carries the one-line message the ``gcm-ortho`` command prints (a
setting is named by its key, as you passed it)."""


class GcmOrthoError(Exception):
    """Anything gcm-ortho refuses or fails at."""


class InputError(GcmOrthoError):
    """An input file is not what its format promises (truncated, corrupt,
    inconsistent), or a camera file or manifest has a bad field."""


class InputOutputError(InputError, OSError):
    """The operating system refused a read or a write."""


class UnsupportedError(InputError):
    """A well-formed file uses a feature gcm-ortho does not read."""


class LimitError(InputError):
    """A size or count beyond what gcm-ortho accepts (it protects memory)."""


class SettingError(GcmOrthoError, ValueError):
    """A setting out of range, unknown, or contradicting another."""


class GeometryError(GcmOrthoError):
    """The geometry cannot be solved (a degenerate camera, an empty footprint)."""


class InternalError(GcmOrthoError):
    """A fault of gcm-ortho itself, not of the inputs: a bug to report."""


class CancelledError(GcmOrthoError):
    """The run was cancelled."""


class GcmOrthoWarning(UserWarning):
    """Doubtful input met, and how it was taken (also in the report's
    ``warnings``)."""


def _warn(message: str) -> None:
    """Says ``message`` as a :class:`GcmOrthoWarning` attributed to the
    caller's line, outside this package (called by the native runs)."""
    import sys
    import warnings

    frame, level = sys._getframe(1), 2
    while frame is not None and frame.f_globals.get("__name__", "").startswith("gcm_ortho"):
        frame, level = frame.f_back, level + 1
    warnings.warn(message, GcmOrthoWarning, stacklevel=level)
