"""Error types of cosim.

Every error a user can cause (bad config, bad rate, bad file) derives from
:class:`CosimError`; the command line turns it into one line on stderr and exit code 2.
"""

from __future__ import annotations


class CosimError(Exception):
    """Base class of every error cosim raises on purpose."""


class ConfigError(CosimError):
    """A configuration key is unknown or its value is out of range."""


class RateError(ConfigError):
    """A period is not a whole number of physics steps."""


class PhysicsDivergenceError(CosimError):
    """The MuJoCo simulation produced non-finite values or MuJoCo warnings."""


class SolverError(CosimError):
    """A tracker's optimiser failed and no fallback was possible."""


class LogReadError(CosimError):
    """An MCAP file cannot be read or lacks what cosim wrote into it."""


class RenderError(CosimError):
    """A video cannot be made: bad render option, unusable log, or the encoder failed."""


class GlBackendError(RenderError):
    """The OpenGL back-end MuJoCo renders with (MUJOCO_GL) is missing or does not start."""


class PluginError(CosimError):
    """A tracker or estimator from outside cosim cannot be loaded or breaks its interface
    (missing module, no ``step`` method, a wrong return type): bad input, exit code 2."""


class TrackerFault(CosimError):
    """A tracker from outside cosim failed during a run (raised, returned a non-finite
    command, overran its time budget): the run ends with ``completed: false``.

    ``detail`` holds what the one-line message leaves out (the traceback of an exception
    in the user's code), for the log's ``/events``."""

    def __init__(self, message: str, detail: str = "") -> None:
        super().__init__(message)
        self.detail = detail
