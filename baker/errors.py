"""Error hierarchy. A BakerError is a user-facing problem: the CLI prints its message on one
line and exits with code 2. Anything else is a bug and keeps its traceback."""


class BakerError(Exception):
    """Base class for every error caused by the user's input or environment."""


class ConfigError(BakerError):
    """Bad option values, bad rig TOML."""


class EnvironmentLoadError(BakerError):
    """The environment file is missing, unsupported, corrupt or unusable."""


class NavError(BakerError):
    """The navigation surface cannot be built or used (for example: nothing walkable)."""


class RigError(BakerError):
    """The rig definition is inconsistent."""


class ExportError(BakerError):
    """An output file cannot be written."""
