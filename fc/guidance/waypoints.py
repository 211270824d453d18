"""fc/guidance/waypoints.py - waypoint navigation: position and mission -> guidance targets.

Pure (no I/O, no clock): the caller passes the GNSS position and speed and gets the altitude,
course and speed targets the guidance (fc/guidance/guidance.py) flies.

Geometry: great circles on the sphere the plant flies over (radius ``NavParams.earth_radius_m``,
the WGS-84 mean radius of hyfc_wire.earth, which fc/mission_mode.py passes in), in unit
vectors (n-vectors) of the Earth-centred frame, so no formula has a singular point: the poles
and the antimeridian are ordinary points (issue 21). A leg P -> W is the great circle with
pole n = P x W / |P x W| (n . X > 0: X is left of the leg). At the vehicle X:

    cross-track  e     = -R asin(n . X)                         (m, + right of the leg)
    to go        s     = R atan2((X' x W) . n, X' . W)          (m, along the leg; < 0 passed)
    leg course   chi   = azimuth at X of n x X'                 (rad, the great circle's course
                                                                  where the vehicle is)

with X' = X - (n . X) n normalised (X's foot on the leg). ``gc_distance_m`` and
``gc_azimuth_rad`` are the great-circle distance and initial course; the unit tests check
them and the leg against pymap3d's geodesics on the same sphere. ``local_ne`` (the old
flat map about home) and ``leg_geometry`` (a leg on that map) remain for tools and tests that
plot a track on a map.

Course law: the leg runs from the previous point P (the previous waypoint, or the position
where the leg was started) to the active waypoint W; its course is chi_leg = atan2(dE, dN).
e is the cross-track error (m, + right of the leg). The course target turns toward the leg:

    chi_t = chi_leg - chi_int (2 / pi) atan(e / L_xt)

with chi_int the intercept angle (rad) reached far from the leg and L_xt the cross-track
length scale (m). The course loop's time constant is about 20 s at 2250 m/s (12 deg of bank
per degree of course error, docs/guidance.md), so L_xt = 50 km, chi_int = 20 deg gives a
cross-track time constant of L_xt pi / (2 chi_int V) ~ 100 s: five times slower, no overshoot.

Switching: a vehicle at V turning at the bank limit mu_max flies a radius R = V^2 / (g tan
mu_max): at Mach 7 (2250 m/s) and 25 deg, R = 1100 km. To fly onto the next leg, W is
accepted at the turn-anticipation distance d = R tan(|dchi| / 2) ahead of it (dchi the course
change at W), or at the acceptance radius if larger, or when W is passed (the along-track
distance to it <= 0): the test is along the leg, to_go <= d (d >= the acceptance radius,
so a vehicle within it always switches). At a 30 deg turn that is 295 km ahead, at 2 deg 19 km.

Altitude target: the active waypoint's altitude (MSL; a relative-altitude item adds home's).
Speed target: the last DO_CHANGE_SPEED item passed (kept across waypoints). After the last
item the targets are held: the last leg's course, the last altitude and speed (CRUISE-like).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["local_ne", "leg_geometry", "turn_radius_m", "switch_distance_m", "course_target",
           "orbit_radius_m", "orbit_course", "NavParams", "WaypointNavigator", "PointNavigator",
           "G0_M_S2", "ORBIT_TAN_FRACTION", "EARTH_RADIUS_M", "unit_vector", "gc_distance_m",
           "gc_azimuth_rad", "gc_leg", "gc_pole", "gc_course_rad", "gc_destination"]

G0_M_S2 = 9.80665
#: The sphere's radius (m): hyfc_wire.earth.EARTH_RADIUS_M (this package imports nothing of
#: ours but fc.control, so fc/mission_mode.py hands the contract's value to NavParams;
#: tests/unit/control/test_waypoints_sphere.py checks that the two agree)
EARTH_RADIUS_M = 6371008.7714
WGS84_A_M = 6378137.0
WGS84_E2 = 6.69437999014e-3
#: An orbit is flown at tan(mu) = ORBIT_TAN_FRACTION tan(mu_max): a quarter of the bank's
#: tangent is left to the course loop's corrections (docs/guidance.md, "Return and reposition")
ORBIT_TAN_FRACTION = 0.75
CMD_WAYPOINT = 16
CMD_CHANGE_SPEED = 178
FRAMES_REL = (3, 6)          # GLOBAL_RELATIVE_ALT(_INT): altitude above home


def _radii(lat0_deg: float) -> tuple[float, float]:
    s = math.sin(math.radians(lat0_deg))
    d = 1.0 - WGS84_E2 * s * s
    return WGS84_A_M * (1.0 - WGS84_E2) / d ** 1.5, WGS84_A_M / math.sqrt(d)


def local_ne(lat_deg: float, lon_deg: float, lat0_deg: float, lon0_deg: float) -> tuple[float, float]:
    """(north m, east m) of (lat, lon) from (lat0, lon0), flat earth about (lat0, lon0)."""
    rn, re = _radii(lat0_deg)
    dlon = (lon_deg - lon0_deg + 180.0) % 360.0 - 180.0
    return (math.radians(lat_deg - lat0_deg) * rn,
            math.radians(dlon) * re * math.cos(math.radians(lat0_deg)))


def _wrap(a: float) -> float:
    """Angle wrapped to [-pi, pi)."""
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def leg_geometry(p_ne: tuple, w_ne: tuple, x_ne: tuple) -> tuple[float, float, float, float]:
    """Leg P -> W and position X (north, east in m).

    Returns (chi_leg rad, cross-track e m (+ right of the leg), along-track distance to go to
    W m (< 0 once passed), distance X -> W m). A leg shorter than 1 m has the course X -> W.
    """
    dn, de = w_ne[0] - p_ne[0], w_ne[1] - p_ne[1]
    xn, xe = w_ne[0] - x_ne[0], w_ne[1] - x_ne[1]
    dist = math.hypot(xn, xe)
    length = math.hypot(dn, de)
    if length < 1.0:
        return math.atan2(xe, xn), 0.0, dist, dist
    un, ue = dn / length, de / length
    to_go = xn * un + xe * ue
    e = xn * ue - xe * un             # the vehicle's offset across the leg, + right
    return math.atan2(ue, un), e, to_go, dist


def unit_vector(lat_deg: float, lon_deg: float) -> tuple[float, float, float]:
    """The unit vector (Earth-centred axes: x through 0 N 0 E, z through the north pole) of
    the point (lat, lon) in degrees."""
    la, lo = math.radians(lat_deg), math.radians(lon_deg)
    c = math.cos(la)
    return (c * math.cos(lo), c * math.sin(lo), math.sin(la))


def _dot(a, b) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _cross(a, b) -> tuple[float, float, float]:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _norm(a) -> float:
    return math.sqrt(_dot(a, a))


def _azimuth(x, d) -> float:
    """Azimuth (rad, clockwise from north, [0, 2 pi)) of the direction ``d`` at the point
    ``x`` (unit vectors). At a pole north is taken along longitude 180 (east = E's y axis),
    as the plant does (docs/plant.md 5a)."""
    rho = math.hypot(x[0], x[1])
    if rho > 1e-12:
        east = (-x[1] / rho, x[0] / rho, 0.0)
    else:
        east = (0.0, 1.0, 0.0)
    north = _cross(x, east)            # up x east = north
    return math.atan2(_dot(d, east), _dot(d, north)) % (2.0 * math.pi)


def gc_distance_m(a, b, r_m: float = EARTH_RADIUS_M) -> float:
    """Great-circle distance (m) between unit vectors ``a`` and ``b`` on the sphere of radius
    ``r_m`` (atan2 form: accurate at every separation, 0 and pi included)."""
    return r_m * math.atan2(_norm(_cross(a, b)), _dot(a, b))


def gc_azimuth_rad(a, b) -> float:
    """Initial course (rad, [0, 2 pi)) of the great circle from ``a`` to ``b``."""
    ab = _dot(a, b)
    return _azimuth(a, (b[0] - ab * a[0], b[1] - ab * a[1], b[2] - ab * a[2]))


def gc_pole(x, chi_rad: float) -> tuple[float, float, float]:
    """Pole n of the great circle through ``x`` flown at course ``chi_rad``: n = x x d with d
    the course's direction (n . y > 0: y is left of the track)."""
    rho = math.hypot(x[0], x[1])
    east = (-x[1] / rho, x[0] / rho, 0.0) if rho > 1e-12 else (0.0, 1.0, 0.0)
    north = _cross(x, east)
    c, s = math.cos(chi_rad), math.sin(chi_rad)
    d = (c * north[0] + s * east[0], c * north[1] + s * east[1], c * north[2] + s * east[2])
    return _cross(x, d)


def gc_course_rad(n, x) -> float:
    """Course (rad, [0, 2 pi)) at ``x`` along the great circle of pole ``n`` (or, off it, along
    the circle parallel to it through ``x``): the azimuth of n x x."""
    return _azimuth(x, _cross(n, x))


def gc_leg(p, w, x, r_m: float = EARTH_RADIUS_M) -> tuple[float, float, float, float]:
    """The great-circle leg P -> W and the vehicle X (unit vectors; module docstring).

    Returns (leg course at X rad, cross-track e m (+ right of the leg), along-track distance to
    go to W m (< 0 once passed), distance X -> W m). A leg shorter than 1 m has the course
    X -> W.
    """
    dist = gc_distance_m(x, w, r_m)
    n = _cross(p, w)
    length = _norm(n)
    if length * r_m < 1.0:
        return gc_azimuth_rad(x, w), 0.0, dist, dist
    n = (n[0] / length, n[1] / length, n[2] / length)
    nx = _dot(n, x)
    foot = (x[0] - nx * n[0], x[1] - nx * n[1], x[2] - nx * n[2])
    fl = _norm(foot)
    if fl < 1e-15:                      # X at the leg's pole: every direction is across
        return gc_azimuth_rad(x, w), 0.0, dist, dist
    foot = (foot[0] / fl, foot[1] / fl, foot[2] / fl)
    to_go = r_m * math.atan2(_dot(_cross(foot, w), n), _dot(foot, w))
    e = -r_m * math.asin(min(1.0, max(-1.0, nx)))
    return _azimuth(x, _cross(n, foot)), e, to_go, dist


def turn_radius_m(v_m_s: float, mu_max_rad: float) -> float:
    """Radius (m) of a level coordinated turn at speed ``v_m_s`` and bank ``mu_max_rad``."""
    return v_m_s * v_m_s / (G0_M_S2 * math.tan(mu_max_rad))


def switch_distance_m(v_m_s: float, mu_max_rad: float, dchi_rad: float, accept_m: float) -> float:
    """Distance before a waypoint (m) at which to switch to the next leg: the turn
    anticipation R tan(|dchi|/2), at least ``accept_m``."""
    d = turn_radius_m(v_m_s, mu_max_rad) * math.tan(min(abs(_wrap(dchi_rad)), 0.99 * math.pi) / 2)
    return max(d, accept_m)


def course_target(chi_leg_rad: float, e_m: float, xt_len_m: float, chi_int_rad: float) -> float:
    """Course target (rad, [0, 2pi)) toward the leg: chi_leg - chi_int (2/pi) atan(e / L)."""
    chi = chi_leg_rad - chi_int_rad * (2.0 / math.pi) * math.atan(e_m / xt_len_m)
    return chi % (2.0 * math.pi)


@dataclass(slots=True)
class NavParams:
    """Navigator parameters (SI)."""
    accept_m: float = 2000.0            # least acceptance radius (m); an item's param2 > 0 overrides
    xt_len_m: float = 50000.0           # cross-track length scale L_xt (m)
    chi_int_rad: float = math.radians(20.0)   # intercept angle far from the leg (rad)
    mu_max_rad: float = math.radians(25.0)    # bank used for turn anticipation (GE_MU_MAX)
    earth_radius_m: float = EARTH_RADIUS_M    # the sphere's radius (hyfc_wire.earth)


class WaypointNavigator:
    """Flies a mission (fc/mission.py ``Mission``: ``count``, ``current``, ``finished``,
    ``version``, ``item(seq)``, ``advance(seq)``) to guidance targets.

        nav = WaypointNavigator(NavParams())
        nav.start(mission, home, pos)           # on entering MISSION
        every guidance period:
            h_m, chi_rad, v_m_s, outputs = nav.step(mission, lat, lon, v_m_s)
            (send ``outputs``: the mission's MISSION_ITEM_REACHED / MISSION_CURRENT)

    ``home``: (lat deg, lon deg, alt m MSL); ``pos``: (lat deg, lon deg).
    """

    def __init__(self, params: NavParams | None = None) -> None:
        self.p = params or NavParams()
        self.home = (0.0, 0.0, 0.0)
        self.prev = unit_vector(0.0, 0.0)   # start of the active leg (unit vector)
        self.h_t = math.nan              # the targets (m MSL, rad, m/s; NaN: none yet)
        self.chi_t = math.nan
        self.v_t = math.nan
        self.chi_leg = 0.0
        self.xt_m = 0.0                  # cross-track error (m, + right)
        self.to_go_m = 0.0               # along-track distance to the active waypoint (m)
        self.switch_m = 0.0              # switching distance in force (m)
        self._version = -1
        self._wp_seq = -1

    def start(self, mission, home: tuple, pos: tuple, h_m: float, chi_rad: float,
              v_m_s: float) -> None:
        """Start (or restart) at position ``pos`` (lat, lon deg) with the current altitude
        (m MSL), course (rad) and speed (m/s) as the initial targets; the first leg starts
        here."""
        self.home = tuple(float(v) for v in home)
        self.prev = unit_vector(pos[0], pos[1])
        self.h_t, self.chi_t, self.v_t = float(h_m), float(chi_rad), float(v_m_s)
        self._version = mission.version
        self._wp_seq = -1

    def _wp(self, it: dict) -> tuple[tuple[float, float, float], float]:
        """Unit vector and altitude (m MSL) of a waypoint item."""
        alt = it["z"] + (self.home[2] if it["frame"] in FRAMES_REL else 0.0)
        return unit_vector(it["x"] * 1e-7, it["y"] * 1e-7), alt

    def _next_wp(self, mission, seq: int):
        """The first waypoint item after ``seq`` (dict) or None."""
        for s in range(seq + 1, mission.count):
            it = mission.item(s)
            if it["command"] == CMD_WAYPOINT:
                return it
        return None

    def step(self, mission, lat_deg: float, lon_deg: float, v_m_s: float) -> tuple:
        """One navigation step at the GNSS position (deg) and speed (m/s). Returns
        (h_t m MSL, chi_t rad, v_t m/s, outputs of the mission to send)."""
        out: list = []
        x = unit_vector(lat_deg, lon_deg)
        r_m = self.p.earth_radius_m
        if mission.version != self._version:          # new mission or set current: new leg
            self._version = mission.version
            self.prev = x
        for _ in range(mission.count + 1):            # DO items apply at once, in order
            if mission.finished or mission.count == 0:
                return self.h_t, self.chi_t, self.v_t, out   # hold the last targets
            seq = mission.current
            it = mission.item(seq)
            if it["command"] == CMD_CHANGE_SPEED:
                if it["param2"] > 0.0:
                    self.v_t = it["param2"]
                out += mission.advance(seq)
                continue
            w, alt = self._wp(it)
            chi_leg, e, to_go, _ = gc_leg(self.prev, w, x, r_m)
            nxt = self._next_wp(mission, seq)
            dchi = 0.0
            if nxt is not None:           # the course change at W: next leg's - this leg's
                chi_at_w, _, _, _ = gc_leg(self.prev, w, w, r_m)
                dchi = gc_azimuth_rad(w, self._wp(nxt)[0]) - chi_at_w
            accept = it["param2"] if it["param2"] > 0.0 else self.p.accept_m
            self.switch_m = switch_distance_m(max(v_m_s, 1.0), self.p.mu_max_rad, dchi, accept)
            self.chi_leg, self.xt_m, self.to_go_m = chi_leg, e, to_go
            self.h_t = alt
            self.chi_t = course_target(chi_leg, e, self.p.xt_len_m, self.p.chi_int_rad)
            if to_go <= self.switch_m:        # within the switching distance, or passed
                self.prev = w
                if mission.current + 1 >= mission.count:   # the last: hold the leg's course
                    self.chi_t = chi_leg % (2.0 * math.pi)
                out += mission.advance(seq)
                continue
            break
        return self.h_t, self.chi_t, self.v_t, out


def orbit_radius_m(v_m_s: float, mu_max_rad: float) -> float:
    """Least orbit radius (m) flown at speed ``v_m_s`` with the bank limit ``mu_max_rad``: the
    level-turn radius at tan(mu) = ORBIT_TAN_FRACTION tan(mu_max) (Mach 7.5, 29.8 deg: 1200 km)."""
    return v_m_s * v_m_s / (G0_M_S2 * ORBIT_TAN_FRACTION * math.tan(mu_max_rad))


def orbit_course(x_ne: tuple, c_ne: tuple, radius_m: float, clockwise: bool, xt_len_m: float,
                 chi_int_rad: float) -> float:
    """Course target (rad, [0, 2pi)) onto and around the circle of ``radius_m`` about ``c_ne``
    (north, east m) from the position ``x_ne``.

    With b the bearing to the centre and r the distance to it (s = +1 clockwise, -1 not):
    outside the circle, the tangent to it, chi = b - s asin(R / r) (straight at the centre from
    afar, along the circle at r = R); inside, along the circle turned outward by the
    cross-track law, chi = b - s (pi/2 + chi_int (2/pi) atan((R - r) / L_xt)). Continuous at
    r = R.
    """
    dn, de = c_ne[0] - x_ne[0], c_ne[1] - x_ne[1]
    r = math.hypot(dn, de)
    b = math.atan2(de, dn)
    s = 1.0 if clockwise else -1.0
    if r > radius_m:
        chi = b - s * math.asin(radius_m / r)
    else:
        chi = b - s * (0.5 * math.pi
                       + chi_int_rad * (2.0 / math.pi) * math.atan((radius_m - r) / xt_len_m))
    return chi % (2.0 * math.pi)


def gc_destination(x, chi_rad: float, dist_m: float, r_m: float = EARTH_RADIUS_M
                   ) -> tuple[float, float, float]:
    """The unit vector reached from ``x`` along the great circle of initial course ``chi_rad``
    after ``dist_m`` (m) on the sphere of radius ``r_m``: cos(d) X + sin(d) D, D the course's
    direction at X (= n x X with n = :func:`gc_pole`)."""
    n = gc_pole(x, chi_rad)
    d = _cross(n, x)
    dl = _norm(d)
    d = (d[0] / dl, d[1] / dl, d[2] / dl)
    a = dist_m / r_m
    c, s = math.cos(a), math.sin(a)
    y = (c * x[0] + s * d[0], c * x[1] + s * d[1], c * x[2] + s * d[2])
    yl = _norm(y)
    return (y[0] / yl, y[1] / yl, y[2] / yl)


def _polar_ne(x, c, r_m: float) -> tuple[float, float]:
    """(north, east) m of the point ``c`` seen from ``x`` on the plane tangent at ``x``: its
    great-circle distance along its great-circle bearing (exact in both at ``x``, where the
    course is flown)."""
    d = gc_distance_m(x, c, r_m)
    b = gc_azimuth_rad(x, c)
    return d * math.cos(b), d * math.sin(b)


class PointNavigator:
    """Fly to a point and circle over it (RTL, DO_REPOSITION), or circle a centre (DO_ORBIT).

    On the sphere (radius ``NavParams.earth_radius_m``), positions as unit vectors
    (:func:`unit_vector`), so a return from the far side of the Earth or over a pole flies the
    great circle home. ``goto``: the circle of ``radius_m`` is placed through the point,
    tangent there to the great circle from the start to the point (``clockwise``: its centre to
    the right of it), and flown with :func:`orbit_course` evaluated at each step on the plane
    tangent at the vehicle (the centre at its great-circle distance and bearing): the tangent
    to the circle from afar is the great circle at the point, so the vehicle flies straight at
    the point, passes over it and circles on, over the point once a lap. ``orbit``: circles a
    given centre. ``arrived`` turns True once the point is within the acceptance distance
    along the great circle from the start, or passed.
    """

    def __init__(self, params: NavParams | None = None) -> None:
        self.p = params or NavParams()
        self.start_u = (1.0, 0.0, 0.0)
        self.point_u = (1.0, 0.0, 0.0)
        self.centre_u = (1.0, 0.0, 0.0)
        self.radius_m = 0.0
        self.clockwise = True
        self.arrived = False
        self.dist_m = 0.0            # to the point until arrived, then to the circle, m

    def goto(self, start_u: tuple, point_u: tuple, radius_m: float,
             clockwise: bool = True) -> None:
        r_e = self.p.earth_radius_m
        self.start_u, self.point_u = tuple(start_u), tuple(point_u)
        self.radius_m, self.clockwise = float(radius_m), bool(clockwise)
        # the course of the great circle start -> point where it reaches the point
        n = _cross(self.start_u, self.point_u)
        if _norm(n) < 1e-12:                 # start at the point (or its antipode): due north
            chi_at = 0.0
        else:
            chi_at = gc_course_rad(n, self.point_u)
        s = 1.0 if clockwise else -1.0
        self.centre_u = gc_destination(self.point_u, chi_at + s * 0.5 * math.pi,
                                       self.radius_m, r_e)
        self.arrived = False

    def orbit(self, centre_u: tuple, radius_m: float, clockwise: bool = True) -> None:
        self.point_u = self.centre_u = tuple(centre_u)
        self.radius_m, self.clockwise = float(radius_m), bool(clockwise)
        self.arrived = True

    def target_bearing(self, x_u: tuple) -> float:
        """Great-circle bearing (rad) from ``x_u`` to what is flown at: the point until arrived,
        then the circle's centre."""
        return gc_azimuth_rad(x_u, self.centre_u if self.arrived else self.point_u)

    def step(self, x_u: tuple) -> float:
        """Course target (rad) at the position ``x_u`` (unit vector)."""
        r_e = self.p.earth_radius_m
        if not self.arrived:
            _, _, to_go, dist = gc_leg(self.start_u, self.point_u, x_u, r_e)
            self.arrived = to_go <= self.p.accept_m
            self.dist_m = dist
        c_ne = _polar_ne(x_u, self.centre_u, r_e)
        if self.arrived:
            self.dist_m = abs(math.hypot(c_ne[0], c_ne[1]) - self.radius_m)
        return orbit_course((0.0, 0.0), c_ne, self.radius_m, self.clockwise, self.p.xt_len_m,
                            self.p.chi_int_rad)
