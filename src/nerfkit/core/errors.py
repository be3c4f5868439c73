"""Errors nerfkit raises on purpose.

Every user-facing failure (bad data, bad config, bad checkpoint) is a `NerfkitError`
whose message names the file or value at fault and how to fix it. The CLI prints the
message on one line and exits non-zero instead of showing a traceback.
"""


class NerfkitError(Exception):
    """Base class for errors with a message meant for the user."""


class DataError(NerfkitError):
    """A dataset on disk is missing, unreadable or inconsistent."""


class ConfigError(NerfkitError):
    """A configuration value is out of range or inconsistent with another."""


class CheckpointError(NerfkitError):
    """A checkpoint is missing, corrupted, foreign, or from a different model."""
