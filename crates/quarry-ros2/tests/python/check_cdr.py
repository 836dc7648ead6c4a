"""Checks quarry's CDR messages and type hashes against rosbags (an independent implementation).

Usage: check_cdr.py DIR. DIR holds, per message type T (`pkg__msg__Name`): T.cdr (quarry's
serialized sample), T.msg (quarry's ros2msg definition text), T.hash (quarry's RIHS01 hash).
Standard types are taken from rosbags' ROS 2 Jazzy type store; the others (vision_msgs,
quarry_msgs) are registered from quarry's definition text. Prints one JSON object per type.
"""
import json
import math
import pathlib
import sys

from rosbags.typesys import Stores, get_typestore, get_types_from_msg

SEP = "=" * 80


def full(short):
    pkg, name = short.split("/")
    return f"{pkg}/msg/{name}"


def main():
    d = pathlib.Path(sys.argv[1])
    ts = get_typestore(Stores.ROS2_JAZZY)
    out = []
    for cdr in sorted(d.glob("*.cdr")):
        name = cdr.stem.replace("__", "/")
        text = (d / f"{cdr.stem}.msg").read_text()
        mine = (d / f"{cdr.stem}.hash").read_text().strip()
        standard = name in ts.fielddefs
        if not standard:
            sections = text.split(SEP + "\n")
            types = get_types_from_msg(sections[0], name)
            for sec in sections[1:]:
                head, _, body = sec.partition("\n")
                assert head.startswith("MSG: "), head
                sub = full(head[5:].strip())
                if sub not in ts.fielddefs:
                    types.update(get_types_from_msg(body, sub))
            ts.register(types)
        data = cdr.read_bytes()
        msg = ts.deserialize_cdr(data, name)
        again = ts.serialize_cdr(msg, name)
        rec = {
            "type": name,
            "standard": standard,
            "hash_rosbags": ts.hash_rihs01(name),
            "hash_quarry": mine,
            "bytes_equal": bytes(again) == data,
            "len": len(data),
        }
        if name == "sensor_msgs/msg/LaserScan":
            rec["ranges"] = [float(x) if math.isfinite(x) else None for x in msg.ranges]
            rec["frame_id"] = msg.header.frame_id
            rec["stamp"] = [msg.header.stamp.sec, msg.header.stamp.nanosec]
        if name == "quarry_msgs/msg/TrackArray":
            rec["tracks"] = [[t.id, t.x, t.y, t.vx, t.vy] for t in msg.tracks]
        if name == "vision_msgs/msg/Detection2DArray":
            rec["ids"] = [x.id for x in msg.detections]
        out.append(rec)
    print(json.dumps(out))


if __name__ == "__main__":
    main()
