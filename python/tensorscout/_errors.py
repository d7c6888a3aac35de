"""The exceptions of tensorscout. Each carries the one-line message the command line prints."""


class Error(Exception):
    """Every error tensorscout raises."""


class UsageError(Error, ValueError):
    """A config key, argument value or option is invalid (the command line's exit code 2)."""


class SceneError(Error):
    """A scene file could not be read or is not a usable scene."""


class MissingFileError(Error, FileNotFoundError):
    """A file that was named does not exist."""


class FileError(Error, OSError):
    """Any other input/output failure on a named file."""


class RunError(Error, RuntimeError):
    """A run-time failure (a run that ended with termination ``error``, a planner's failure)."""


class InternalError(Error, RuntimeError):
    """A bug inside tensorscout (a Rust panic), caught before it could end the interpreter."""
