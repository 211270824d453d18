"""tools/mavproxy_hyfc.py - a MAVProxy module that teaches MAVProxy the hyfc vehicle.

Stock MAVProxy names the modes of a generic fixed-wing autopilot with ArduPlane's table and
reads integer parameters as ArduPilot sends them (the number cast to float). hyfc sends its
modes as ``custom_mode`` values MAVProxy cannot name and its integer parameters bytewise, as
the MAVLink spec, PX4, MAVSDK and QGroundControl expect (docs/fc.md section 7). Loaded, this
module gives MAVProxy both:

- the mode names: the prompt and "Mode ..." announcements show the hyfc names (MANUAL,
  COORDINATED, UNCOORDINATED, FAILSAFE, CRUISE, GUIDED, MISSION, RTL); ``mode`` lists them and
  ``mode COORDINATED`` (or just ``COORDINATED``) sets one, sending MAV_CMD_DO_SET_MODE with the
  hyfc mode number (so MISSION, whose custom_mode is above 2^24, travels exactly as 6);
- the parameter encoding: MAVProxy's param module decodes and sends INT32 parameters bytewise
  for a hyfc vehicle (what it does for PX4), so ``param show/set`` print and set whole numbers.

A vehicle is hyfc when its HEARTBEAT says autopilot GENERIC and carries one of the
``custom_mode`` values of fc/modes.py; other vehicles on the same MAVProxy are left alone.

Use (after ``pip install -e .``)::

    mavproxy.py --master=udpin:127.0.0.1:14550 --load-module tools.mavproxy_hyfc
    # or, inside MAVProxy:  module load tools.mavproxy_hyfc
"""
from __future__ import annotations

from MAVProxy.modules.lib import mp_module
from pymavlink import mavutil

from fc.modes import MODE_WIRE, FlightMode

ML = mavutil.mavlink
#: HEARTBEAT custom_mode -> name, and name -> the number DO_SET_MODE param2 takes
NAME_BY_CUSTOM = {wire: mode.name for mode, wire in MODE_WIRE.items()}
NUMBER_BY_NAME = {mode.name: int(mode) for mode in FlightMode}


def is_hyfc_heartbeat(m) -> bool:
    return (m.get_type() == "HEARTBEAT" and m.autopilot == ML.MAV_AUTOPILOT_GENERIC
            and m.type != ML.MAV_TYPE_GCS and m.custom_mode in NAME_BY_CUSTOM)


class HyfcModule(mp_module.MPModule):
    """Mode names and bytewise integer parameters for hyfc vehicles (see the module docstring)."""

    def __init__(self, mpstate):
        super().__init__(mpstate, "hyfc", "hyfc mode names and parameter encoding", public=True)
        self.hyfc_sysids: set[int] = set()
        self.hooked: set[int] = set()       # id() of the masters whose mode table we extend
        self._hook_masters()

    def _hook_masters(self) -> None:
        for master in self.mpstate.mav_master:
            if id(master) in self.hooked:
                continue
            self.hooked.add(id(master))
            master.message_hooks.append(self._name_mode)
            stock = master.mode_mapping

            def mode_mapping(master=master, stock=stock):
                if master.sysid in self.hyfc_sysids:
                    return dict(NUMBER_BY_NAME)
                return stock()
            master.mode_mapping = mode_mapping

    def _name_mode(self, master, m) -> None:
        """pymavlink message hook: runs after it named the mode (as ArduPlane) from HEARTBEAT."""
        if is_hyfc_heartbeat(m):
            src = m.get_srcSystem()
            self.hyfc_sysids.add(src)
            master.sysid_state[src].flightmode = NAME_BY_CUSTOM[m.custom_mode]

    def _bytewise_params(self) -> None:
        """Make the param module decode and send a hyfc vehicle's integers bytewise: its
        per-vehicle autopilot table answers PX4 (the one autopilot it does that for) for
        hyfc system ids, whatever order the modules see the HEARTBEAT in."""
        param = self.module("param")
        for state in getattr(param, "pstate", {}).values():
            if not isinstance(state.autopilot_type_by_sysid, _BytewiseFor):
                state.autopilot_type_by_sysid = _BytewiseFor(state.autopilot_type_by_sysid,
                                                             self.hyfc_sysids)

    def mavlink_packet(self, m) -> None:
        if self.hyfc_sysids:
            self._bytewise_params()

    def idle_task(self) -> None:
        self._hook_masters()                # links added later (``link add``)
        if self.hyfc_sysids:
            self._bytewise_params()


class _BytewiseFor(dict):
    """MAVProxy's autopilot-type-by-sysid table, answering PX4 for hyfc system ids."""

    def __init__(self, base: dict, hyfc_sysids: set[int]) -> None:
        super().__init__(base)
        self.hyfc_sysids = hyfc_sysids

    def get(self, sysid, default=None):
        if sysid in self.hyfc_sysids:
            return ML.MAV_AUTOPILOT_PX4
        return super().get(sysid, default)


def init(mpstate):
    """MAVProxy entry point."""
    return HyfcModule(mpstate)
