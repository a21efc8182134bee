"""The runtime: one event loop from a source to estimators, a state snapshot, the navigator and sinks.

The plug-in points it connects are the Protocols of :mod:`tourbot.interfaces`; what it produces is
the :class:`tourbot.snapshot.StateSnapshot` (both in the bottom layer, so that every part can speak
them without importing the runtime).
"""

from tourbot.runtime.loop import Runtime, RuntimeConfig, RuntimeControlError

__all__ = ["Runtime", "RuntimeConfig", "RuntimeControlError"]
