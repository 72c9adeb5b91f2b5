"""Exception hierarchy: one root, one subclass per area."""

from __future__ import annotations


class InitselError(Exception):
    """Root of every error raised on purpose by initsel_ros."""


class ConfigError(InitselError):
    """A parameter or configuration file is invalid."""


class ModelFileError(InitselError):
    """A model file is missing, malformed or inconsistent."""


class DatasetError(InitselError):
    """A sequence (TUM folder or bag) is missing, malformed or inconsistent."""


class ImageConversionError(InitselError):
    """An image message cannot be converted to a numpy array."""


class GeometryError(InitselError):
    """Arguments to a geometry routine have the wrong shape or values."""


class StatusError(InitselError):
    """A status message does not follow the :class:`~initsel_ros.status.FrameStatus` schema."""


__all__ = [
    'ConfigError',
    'DatasetError',
    'GeometryError',
    'ImageConversionError',
    'InitselError',
    'ModelFileError',
    'StatusError',
]
