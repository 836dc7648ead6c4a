//! How people move: the 5 ms motion integrator behind every [`Motion`] kind (steering, braking on
//! routes, the visit script, stop-and-go pauses) with its obstacle and person–person avoidance.

use super::ROUTE_ACCEL;
use super::people::{Motion, PersonSpec, PersonState};
use super::room::Room;
use quarry_core::Point2;
use quarry_core::rng::{SeededRng, stream};
use rand::Rng;
use rand_distr::{Distribution, Normal};
use std::f64::consts::PI;

/// Where a [`Motion::Visit`] walker is in its script.
#[derive(Debug, Clone, Copy, PartialEq)]
enum VisitPhase {
    /// Following `enter`, at the given point.
    Enter(usize),
    /// Inside since the given walker time (`PersonState::t`), seconds.
    Inside(f64),
    /// Heading for `door_front` (stay over; entered at the given walker time).
    ToDoor(f64),
    /// Following `exit`, at the given point.
    Exit(usize),
}

/// The motion integrator of one person: its spec, seeded stream, state and script progress.
#[derive(Debug, Clone)]
pub(super) struct Walker {
    pub(super) spec: PersonSpec,
    rng: SeededRng,
    pub(super) state: PersonState,
    prev: PersonState,
    pub(super) alive: bool,
    target: Point2,
    v_leg: f64,
    blocked_s: f64,
    route_idx: usize,
    redraw_s: f64,
    /// Left the simulation for good (end of a [`Motion::Visit`]).
    pub(super) done: bool,
    /// Remaining pause of a [`Motion::StopAndGo`] walker, seconds.
    pause_left: f64,
    phase: VisitPhase,
}

impl Walker {
    pub(super) fn new(spec: PersonSpec, seed: u64) -> Self {
        let mut rng = stream(seed, &[1, u64::from(spec.id)]);
        let a = rng.random_range(0.19..0.25);
        let b = rng.random_range(0.11..0.15);
        let st = PersonState {
            id: spec.id,
            pos: Point2::origin(),
            heading: 0.0,
            speed: 0.0,
            a,
            b,
            t: 0.0,
        };
        Self {
            spec,
            rng,
            state: st,
            prev: st,
            alive: false,
            target: Point2::origin(),
            v_leg: 0.0,
            blocked_s: 0.0,
            route_idx: 0,
            redraw_s: 0.0,
            done: false,
            pause_left: 0.0,
            phase: VisitPhase::Inside(0.0),
        }
    }

    fn draw_speed(&mut self) -> f64 {
        let (lo, hi) = self.spec.speed;
        if hi > lo {
            self.rng.random_range(lo..hi)
        } else {
            lo
        }
    }

    fn pick_waypoint(&mut self, room: &Room) {
        let mut best = room.sample_free(&mut self.rng);
        for _ in 0..100 {
            let p = room.sample_free(&mut self.rng);
            if (p - self.state.pos).norm() > 1.0 && room.segment_clear(self.state.pos, p, 0.5) {
                best = p;
                break;
            }
        }
        self.target = best;
        self.v_leg = self.draw_speed();
    }

    pub(super) fn spawn(&mut self, room: &Room, others: &[Point2]) {
        let p = if let Some(s) = self.spec.spawn {
            Point2::new(s[0], s[1])
        } else {
            let mut p = room.sample_free(&mut self.rng);
            for _ in 0..1000 {
                if others.iter().all(|o| (o - p).norm() >= 1.0) {
                    break;
                }
                p = room.sample_free(&mut self.rng);
            }
            p
        };
        self.state.pos = p;
        self.alive = true;
        match &self.spec.motion {
            Motion::Waypoint | Motion::StopAndGo { .. } => self.pick_waypoint(room),
            Motion::Visit(v) => {
                self.phase = VisitPhase::Enter(0);
                self.target = v.enter.first().map_or(p, |q| Point2::new(q[0], q[1]));
                self.v_leg = self.draw_speed();
            }
            Motion::RandomWalk => {
                self.v_leg = self.draw_speed();
                self.state.heading = self.rng.random_range(-PI..PI);
                self.target = p;
            }
            Motion::Route(r) => {
                self.route_idx = 0;
                self.target = r.first().map_or(p, |q| Point2::new(q[0], q[1]));
                self.v_leg = self.draw_speed();
            }
        }
        let d = self.target - p;
        if d.norm() > 1e-9 && !matches!(self.spec.motion, Motion::RandomWalk) {
            self.state.heading = d.y.atan2(d.x);
        }
        self.state.speed = self.v_leg;
        self.prev = self.state;
    }

    /// One 5 ms step. `others` are the other live people's positions.
    pub(super) fn step(&mut self, room: &Room, others: &[Point2], dt: f64, noise: &Normal<f64>) {
        self.prev = self.state;
        self.state.t += dt;
        if self.pause_left > 0.0 {
            // a stop-and-go walker standing at its waypoint
            self.state.speed = 0.0;
            self.pause_left -= dt;
            if self.pause_left <= 1e-9 {
                self.pause_left = 0.0;
                self.pick_waypoint(room);
            }
            return;
        }
        if matches!(self.phase, VisitPhase::Enter(_) | VisitPhase::Exit(_))
            && matches!(self.spec.motion, Motion::Visit(_))
        {
            self.step_passage(room, others, dt);
            return;
        }
        // desired heading
        let desired = match &self.spec.motion {
            Motion::Waypoint | Motion::Route(_) | Motion::StopAndGo { .. } | Motion::Visit(_) => {
                let d = self.target - self.state.pos;
                if d.norm() < 0.3 {
                    match &self.spec.motion {
                        Motion::Route(r) if !r.is_empty() => {
                            self.route_idx = (self.route_idx + 1) % r.len();
                            let q = r[self.route_idx];
                            self.target = Point2::new(q[0], q[1]);
                            // a scripted walker turns on the spot at the end of a leg
                            let d = self.target - self.state.pos;
                            self.state.heading = d.y.atan2(d.x);
                        }
                        Motion::StopAndGo { pause_s: (lo, hi) } => {
                            let (lo, hi) = (*lo, *hi);
                            self.pause_left = if hi > lo {
                                self.rng.random_range(lo..hi)
                            } else {
                                lo
                            };
                            self.state.speed = 0.0;
                            if self.pause_left <= 0.0 {
                                self.pause_left = 0.0;
                                self.pick_waypoint(room);
                            }
                            return;
                        }
                        Motion::Visit(_) => {
                            if self.visit_waypoint_reached(room, others) {
                                return;
                            }
                        }
                        _ => self.pick_waypoint(room),
                    }
                }
                let d = self.target - self.state.pos;
                d.y.atan2(d.x)
            }
            Motion::RandomWalk => {
                self.redraw_s += dt;
                if self.redraw_s >= 5.0 {
                    self.redraw_s = 0.0;
                    self.v_leg = self.draw_speed();
                }
                let mut h = self.state.heading + 0.8 * dt.sqrt() * noise.sample(&mut self.rng);
                if room.obstacle_distance(self.state.pos) < 0.5
                    || !room.is_free(self.state.pos, 0.0)
                {
                    let [x0, x1, y0, y1] = room.walkable;
                    let c = Point2::new(0.5 * (x0 + x1), 0.5 * (y0 + y1)) - self.state.pos;
                    h = c.y.atan2(c.x);
                }
                h
            }
        };
        let err = quarry_core::wrap_angle(desired - self.state.heading);
        let max_turn = 2.0 * dt;
        let turn = if matches!(self.spec.motion, Motion::RandomWalk) {
            err
        } else {
            err.clamp(-max_turn, max_turn)
        };
        self.state.heading = quarry_core::wrap_angle(self.state.heading + turn);
        let v = if matches!(self.spec.motion, Motion::Route(_)) {
            // brake so as to stop where the turn happens, and accelerate out of it (and out of a
            // stop behind another person) at ROUTE_ACCEL; never quite 0, so the turn is reached
            let to_turn = ((self.target - self.state.pos).norm() - 0.3).max(0.0);
            (2.0 * ROUTE_ACCEL * to_turn)
                .sqrt()
                .min(self.state.speed + ROUTE_ACCEL * dt)
                .min(self.v_leg)
                .max(ROUTE_ACCEL * dt)
        } else {
            self.v_leg
        };
        let (s, c) = self.state.heading.sin_cos();
        let next = Point2::new(self.state.pos.x + v * dt * c, self.state.pos.y + v * dt * s);
        let (free, clear) = step_allowed(room, others, self.state.pos, next);
        if free && clear {
            self.state.pos = next;
            self.state.speed = v;
            self.blocked_s = 0.0;
        } else if free
            && matches!(self.spec.motion, Motion::Route(_))
            && let Some(side) = self.sidestep(room, others, v, dt)
        {
            // A scripted walker blocked by another person yields to its right at half speed
            // instead of standing still: two walkers meeting head-on on their routes would
            // otherwise wait for each other for ever (the first `crossing` version froze both
            // at their second meeting, t ≈ 12.3 s, for the rest of the run).
            self.state.pos = side;
            self.state.speed = 0.5 * v;
            self.blocked_s = 0.0;
        } else {
            // stop and turn in place toward the goal (a body cannot walk into a wall)
            if !free && !matches!(self.spec.motion, Motion::RandomWalk) {
                self.state.heading = desired;
            }
            self.state.speed = 0.0;
            self.blocked_s += dt;
            if self.blocked_s >= 0.5 {
                self.blocked_s = 0.0;
                match self.spec.motion {
                    Motion::Waypoint | Motion::StopAndGo { .. } => self.pick_waypoint(room),
                    Motion::Visit(_) => {
                        // blocked on the way to the door: another waypoint first (waiting
                        // would let visitors converging on the door front jam each other)
                        if let VisitPhase::ToDoor(t_in) = self.phase {
                            self.phase = VisitPhase::Inside(t_in);
                        }
                        self.pick_waypoint(room);
                    }
                    Motion::RandomWalk => {
                        self.state.heading = quarry_core::wrap_angle(self.state.heading + PI / 2.0);
                    }
                    Motion::Route(_) => {}
                }
            }
        }
    }

    /// A [`Motion::Visit`] walker reached its waypoint (inside the room or the door front).
    /// Returns true when the step ends here (the walker turned on the spot into its way out).
    fn visit_waypoint_reached(&mut self, room: &Room, others: &[Point2]) -> bool {
        let Motion::Visit(v) = &self.spec.motion else {
            return false;
        };
        match self.phase {
            VisitPhase::ToDoor(_) => {
                // at the door front: out when the doorway is free, else wait here (nobody
                // spawns meanwhile: the door front is in the lane box)
                self.state.speed = 0.0;
                if v.lane_free(others)
                    && let Some(q) = v.exit.first()
                {
                    self.phase = VisitPhase::Exit(0);
                    self.target = Point2::new(q[0], q[1]);
                    let d = self.target - self.state.pos;
                    self.state.heading = d.y.atan2(d.x);
                }
                return true;
            }
            VisitPhase::Inside(t_in) => {
                let door = Point2::new(v.door_front[0], v.door_front[1]);
                if self.state.t - t_in < v.stay_s {
                    self.pick_waypoint(room);
                } else if room.segment_clear(self.state.pos, door, 0.5) {
                    self.phase = VisitPhase::ToDoor(t_in);
                    self.target = door;
                    self.v_leg = self.draw_speed();
                } else {
                    // no straight way to the door (the pillar, the fridge): a waypoint from
                    // which there is one, if any of 100 draws gives it
                    self.pick_waypoint(room);
                    for _ in 0..100 {
                        let p = room.sample_free(&mut self.rng);
                        if (p - self.state.pos).norm() > 1.0
                            && room.segment_clear(self.state.pos, p, 0.5)
                            && room.segment_clear(p, door, 0.5)
                        {
                            self.target = p;
                            break;
                        }
                    }
                }
            }
            VisitPhase::Enter(_) | VisitPhase::Exit(_) => {}
        }
        false
    }

    /// One step of a scripted [`Motion::Visit`] leg (in or out): straight to the current point
    /// at the leg speed, waiting while another person is within 0.6 m ahead. At the end of
    /// `enter` the waypoints start; at the end of `exit` the person leaves.
    fn step_passage(&mut self, room: &Room, others: &[Point2], dt: f64) {
        let Motion::Visit(v) = &self.spec.motion else {
            return;
        };
        let (route, i) = match self.phase {
            VisitPhase::Enter(i) => (&v.enter, i),
            VisitPhase::Exit(i) => (&v.exit, i),
            VisitPhase::Inside(_) | VisitPhase::ToDoor(_) => return,
        };
        let Some(q) = route.get(i) else {
            return;
        };
        let tgt = Point2::new(q[0], q[1]);
        let d = tgt - self.state.pos;
        let dist = d.norm();
        let step = (self.v_leg * dt).min(dist);
        let next = if dist > 1e-12 {
            self.state.pos + d * (step / dist)
        } else {
            tgt
        };
        let clear = others
            .iter()
            .all(|o| (o - next).norm() >= 0.6 || (o - next).norm() > (o - self.state.pos).norm());
        if !clear {
            self.state.speed = 0.0;
            return;
        }
        self.state.pos = next;
        self.state.speed = step / dt;
        if step < dist {
            return;
        }
        // arrived at the point: the next one, or the end of the leg
        let n = route.len();
        let is_enter = matches!(self.phase, VisitPhase::Enter(_));
        if i + 1 < n {
            let q = route[i + 1];
            self.phase = if is_enter {
                VisitPhase::Enter(i + 1)
            } else {
                VisitPhase::Exit(i + 1)
            };
            self.target = Point2::new(q[0], q[1]);
            let d = self.target - self.state.pos;
            self.state.heading = d.y.atan2(d.x);
        } else if is_enter {
            self.phase = VisitPhase::Inside(self.state.t);
            self.pick_waypoint(room);
        } else {
            self.alive = false;
            self.done = true;
        }
    }

    /// A half-speed step to the walker's right (heading − 90°), if the body stays clear of the
    /// walls, the obstacles and the other people (the same rules as a forward step).
    fn sidestep(&self, room: &Room, others: &[Point2], v: f64, dt: f64) -> Option<Point2> {
        let (s, c) = (self.state.heading - PI / 2.0).sin_cos();
        let pos = self.state.pos;
        let next = Point2::new(pos.x + 0.5 * v * dt * c, pos.y + 0.5 * v * dt * s);
        let (free, clear) = step_allowed(room, others, pos, next);
        (free && clear).then_some(next)
    }

    pub(super) fn at(&self, s: f64) -> PersonState {
        let mut p = self.state;
        p.pos = self.prev.pos + (self.state.pos - self.prev.pos) * s;
        p.heading =
            self.prev.heading + quarry_core::wrap_angle(self.state.heading - self.prev.heading) * s;
        p.t = self.prev.t + (self.state.t - self.prev.t) * s;
        p
    }
}

/// Whether a body may move its centre from `from` to `next`: `free` (the centre keeps 0.35 m from
/// the walls and 0.3 m from obstacles, or does not get closer to an obstacle) and `clear` (it
/// keeps 0.6 m from every other person, or does not get closer to them).
fn step_allowed(room: &Room, others: &[Point2], from: Point2, next: Point2) -> (bool, bool) {
    let [x0, x1, y0, y1] = room.walkable;
    let m = room.inflate - 0.35;
    let inside = next.x >= x0 - m && next.x <= x1 + m && next.y >= y0 - m && next.y <= y1 + m;
    let free = inside
        && (room.obstacle_distance(next) >= 0.3
            || room.obstacle_distance(next) >= room.obstacle_distance(from));
    let clear = others
        .iter()
        .all(|o| (o - next).norm() >= 0.6 || (o - next).norm() > (o - from).norm());
    (free, clear)
}
