"""Plays a ROS 2 robot running rmw_zenoh, for quarry's loopback test (only 127.0.0.1).

It publishes sensor_msgs/msg/LaserScan on /scan the way rmw_zenoh does: the CDR message
serialized by rosbags on the key `<domain>/scan/sensor_msgs::msg::dds_::LaserScan_/<RIHS01 hash
from rosbags>`, with the attachment (sequence number, source timestamp, GID) serialized by
eclipse-zenoh's own serializer (zenoh.ext.z_serialize). Nothing of quarry's encoding is reused.

The scene: one scanner at the origin (270 deg, 0.5 deg steps, 40 Hz) in a walled room; after
--empty seconds one person (an ellipse of 0.22 x 0.13 m, quarry's torso model) walks a straight
line at 0.8 m/s. A few faulty messages are mixed in (truncated CDR, a scan with another beam
count), which quarry must skip and count.

Meanwhile it subscribes to quarry's tracks (`<domain>/quarry/tracks/**`), decodes every sample
with rosbags (quarry_msgs from quarry's .msg files, the others from the Jazzy type store) and
decodes each attachment with zenoh.ext.z_deserialize. It stops once no track has arrived for
--quiet seconds after its last scan, and prints one JSON object: the truth, the track frames and
counts per topic.

Usage: ros2_peer.py --listen EP --connect EP --msg-dir DIR [--seconds S] [--empty S] [--domain N]
       [--quiet S] [--ready FILE]
"""
import argparse
import json
import math
import pathlib
import time

import numpy as np
import zenoh
from zenoh.ext import Int64, z_deserialize, z_serialize
from rosbags.typesys import Stores, get_typestore, get_types_from_msg

N_BEAMS = 541
ANGLE_MIN = -3.0 * math.pi / 4.0
ANGLE_INC = math.radians(0.5)
PERIOD = 0.025
ROOM = (-1.0, 8.0, -4.0, 4.0)  # x0, x1, y0, y1: walls
A, B = 0.22, 0.13  # torso semi-axes
SPEED = 0.8
START, END = (2.0, -2.0), (5.0, 2.0)


def dds(ros_type):
    pkg, _, name = ros_type.rpartition("/")
    return f"{pkg.replace('/', '::')}::dds_::{name}_"


def person_at(t):
    """The person's centre and heading t seconds after entering, or None once arrived."""
    dx, dy = END[0] - START[0], END[1] - START[1]
    length = math.hypot(dx, dy)
    s = SPEED * t
    if t < 0 or s > length:
        return None
    return (START[0] + dx * s / length, START[1] + dy * s / length, math.atan2(dy, dx))


def ranges(person, rng):
    """Ranges of one scan: walls, the person (major axis across the walking direction), noise."""
    ang = ANGLE_MIN + ANGLE_INC * np.arange(N_BEAMS)
    c, s = np.cos(ang), np.sin(ang)
    x0, x1, y0, y1 = ROOM
    with np.errstate(divide="ignore", invalid="ignore"):
        tx = np.where(c > 0, x1 / c, np.where(c < 0, x0 / c, np.inf))
        ty = np.where(s > 0, y1 / s, np.where(s < 0, y0 / s, np.inf))
    r = np.minimum(tx, ty)
    if person is not None:
        px, py, heading = person
        phi = heading + math.pi / 2.0  # the shoulders (major axis) across the walking direction
        cp, sp = math.cos(phi), math.sin(phi)
        # ray o + r d in the ellipse frame: ((u/A)^2 + (v/B)^2 = 1)
        ou = (-px) * cp + (-py) * sp
        ov = -(-px) * sp + (-py) * cp
        du = c * cp + s * sp
        dv = -c * sp + s * cp
        qa = (du / A) ** 2 + (dv / B) ** 2
        qb = 2 * (ou * du / A**2 + ov * dv / B**2)
        qc = (ou / A) ** 2 + (ov / B) ** 2 - 1
        disc = qb * qb - 4 * qa * qc
        hit = disc >= 0
        rr = np.where(hit, (-qb - np.sqrt(np.where(hit, disc, 0))) / (2 * qa), np.inf)
        r = np.where((rr > 0) & (rr < r), rr, r)
    return (r + rng.normal(0.0, 0.01, N_BEAMS)).astype(np.float32)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--listen", required=True)
    ap.add_argument("--connect", required=True)
    ap.add_argument("--msg-dir", required=True)
    ap.add_argument("--domain", type=int, default=0)
    ap.add_argument("--seconds", type=float, default=14.0)
    ap.add_argument("--empty", type=float, default=5.0)
    ap.add_argument("--quiet", type=float, default=4.0)
    ap.add_argument("--ready", help="file written once subscribed and publishing")
    a = ap.parse_args()

    ts = get_typestore(Stores.ROS2_JAZZY)
    types = {}
    for name in ("Track", "TrackArray"):
        text = (pathlib.Path(a.msg_dir) / f"{name}.msg").read_text()
        types.update(get_types_from_msg(text, f"quarry_msgs/msg/{name}"))
    ts.register(types)
    LaserScan = ts.types["sensor_msgs/msg/LaserScan"]
    Header = ts.types["std_msgs/msg/Header"]
    Time = ts.types["builtin_interfaces/msg/Time"]

    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("listen/endpoints", json.dumps([a.listen]))
    conf.insert_json5("connect/endpoints", json.dumps([a.connect]))
    conf.insert_json5("scouting/multicast/enabled", "false")
    session = zenoh.open(conf)

    got = {"tracks": [], "poses": 0, "markers": 0, "other": [], "errors": []}
    last_track = [time.time()]

    def on_sample(sample):
        try:
            key = str(sample.key_expr)
            att = sample.attachment
            seq, stamp, gid = z_deserialize(
                tuple[Int64, Int64, bytes], att
            )
            gid = bytes(gid)
            data = sample.payload.to_bytes()
            if "::TrackArray_/" in key:
                h = key.rsplit("/", 1)[1]
                assert h == ts.hash_rihs01("quarry_msgs/msg/TrackArray"), h
                m = ts.deserialize_cdr(data, "quarry_msgs/msg/TrackArray")
                got["tracks"].append(
                    {
                        "key": key,
                        "received": time.time(),
                        "seq": int(seq),
                        "source_ns": int(stamp),
                        "gid_len": len(gid),
                        "stamp": m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec,
                        "frame_id": m.header.frame_id,
                        "rows": [[t.id, t.x, t.y, t.vx, t.vy, t.status] for t in m.tracks],
                    }
                )
                last_track[0] = time.time()
            elif "::PoseArray_/" in key:
                assert key.rsplit("/", 1)[1] == ts.hash_rihs01("geometry_msgs/msg/PoseArray")
                ts.deserialize_cdr(data, "geometry_msgs/msg/PoseArray")
                got["poses"] += 1
            elif "::MarkerArray_/" in key:
                assert key.rsplit("/", 1)[1] == ts.hash_rihs01(
                    "visualization_msgs/msg/MarkerArray"
                )
                ts.deserialize_cdr(data, "visualization_msgs/msg/MarkerArray")
                got["markers"] += 1
            else:
                got["other"].append(key)
        except Exception as e:  # reported, and the test fails on it
            got["errors"].append(repr(e))

    sub = session.declare_subscriber(f"{a.domain}/quarry/tracks/**", on_sample)
    scan_type = "sensor_msgs/msg/LaserScan"
    key = f"{a.domain}/scan/{dds(scan_type)}/{ts.hash_rihs01(scan_type)}"
    pub = session.declare_publisher(key)
    gid = bytes(range(16))
    ready_at = time.time()
    if a.ready:
        pathlib.Path(a.ready).write_text("ready\n")
    rng = np.random.default_rng(7)
    truth = []
    faults = {"truncated": 0, "beam_count": 0}
    t0 = time.time()
    k = 0
    seq = 0
    while True:
        # a scanner's driver stamps each scan with its capture time, which comes at a steady
        # period; when this process is starved (a busy machine) the scan goes out late, with
        # the stamp it was captured at, as a real one delivered late would
        t = t0 + k * PERIOD
        now = time.time()
        if t > now:
            time.sleep(t - now)
        if t - t0 > a.seconds:
            break
        p = person_at(t - t0 - a.empty)
        n = N_BEAMS
        msg = LaserScan(
            header=Header(
                stamp=Time(sec=int(t), nanosec=int((t - int(t)) * 1e9)), frame_id="laser"
            ),
            angle_min=ANGLE_MIN,
            angle_max=ANGLE_MIN + ANGLE_INC * (n - 1),
            angle_increment=ANGLE_INC,
            time_increment=0.0,
            scan_time=PERIOD,
            range_min=0.05,
            range_max=30.0,
            ranges=ranges(p, rng),
            intensities=np.zeros(0, dtype=np.float32),
        )
        data = bytes(ts.serialize_cdr(msg, scan_type))
        if k == 90:  # a truncated message
            data = data[: len(data) // 2]
            faults["truncated"] += 1
        if k == 91:  # a scan with fewer beams
            msg.ranges = msg.ranges[:-40]
            msg.angle_max = ANGLE_MIN + ANGLE_INC * (n - 41)
            data = bytes(ts.serialize_cdr(msg, scan_type))
            faults["beam_count"] += 1
        seq += 1
        att = z_serialize((Int64(seq), Int64(int(t * 1e9)), gid))
        pub.put(data, attachment=att)
        if p is not None:
            truth.append([t, p[0], p[1]])
        k += 1
    sent_end = time.time()
    while time.time() - max(last_track[0], sent_end) < a.quiet:
        time.sleep(0.05)
    sub.undeclare()
    session.close()
    print(
        json.dumps(
            {
                "scans_sent": k,
                "ready_at": ready_at,
                "first_scan_at": t0,
                "faults": faults,
                "attachment_len": len(att.to_bytes()),
                "truth": truth,
                **got,
            }
        )
    )


if __name__ == "__main__":
    main()
