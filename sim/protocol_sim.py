"""pyserial URL handler for ``sim://`` (pyserial imports ``<package>.protocol_<scheme>``); see sim.transport."""

from sim.transport import Serial

__all__ = ["Serial"]
