"""Reads a quarry MCAP with the Python `mcap` reader and `mcap-ros2-support`'s decoder (tools
nobody at quarry wrote) and prints what it decoded as one JSON object:

- profile, and per topic: schema name, schema encoding, message encoding, message count;
- `decoded`: messages decoded (every message is decoded; an undecodable one raises);
- `tracks`: per `quarry_msgs/msg/TrackArray` topic, [log_time_ns, id, x, y] rows;
- `markers`: per MarkerArray topic, the [id, x, y] rows of its last message (DELETEALL skipped);
- `poses`: per PoseStamped topic, [log_time_ns, x, y, yaw] rows;
- `detections`: per Detection2DArray on /detections, [log_time_ns, id, x, y, w, h] rows
  (top-left corner from the box centre);
- `scans`: per LaserScan topic, the number of beams of the first message and the message count.

Usage: read_mcap.py FILE.mcap
"""
import json
import math
import sys

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory


def main():
    path = sys.argv[1]
    out = {"topics": {}, "decoded": 0, "tracks": {}, "markers": {}, "poses": {},
           "detections": [], "scans": {}}
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        header = reader.get_header()
        out["profile"] = header.profile
        summary = reader.get_summary()
        for ch in summary.channels.values():
            sc = summary.schemas[ch.schema_id]
            out["topics"][ch.topic] = {
                "schema": sc.name,
                "schema_encoding": sc.encoding,
                "message_encoding": ch.message_encoding,
                "count": summary.statistics.channel_message_counts.get(ch.id, 0),
            }
        for schema, channel, message, msg in reader.iter_decoded_messages():
            out["decoded"] += 1
            t = message.log_time
            if schema.name == "quarry_msgs/msg/TrackArray":
                rows = out["tracks"].setdefault(channel.topic, [])
                for tr in msg.tracks:
                    rows.append([t, tr.id, tr.x, tr.y])
            elif schema.name == "visualization_msgs/msg/MarkerArray":
                out["markers"][channel.topic] = [
                    [m.id, m.pose.position.x, m.pose.position.y]
                    for m in msg.markers if m.action != 3 and m.type != 9]
            elif schema.name == "geometry_msgs/msg/PoseStamped":
                q = msg.pose.orientation
                out["poses"].setdefault(channel.topic, []).append(
                    [t, msg.pose.position.x, msg.pose.position.y,
                     2.0 * math.atan2(q.z, q.w)])
            elif channel.topic == "/detections":  # the tracker's, not the ground truth
                for d in msg.detections:
                    c = d.bbox.center.position
                    w, h = d.bbox.size_x, d.bbox.size_y
                    out["detections"].append([t, d.id, c.x - w / 2, c.y - h / 2, w, h])
            elif schema.name == "sensor_msgs/msg/LaserScan":
                s = out["scans"].setdefault(channel.topic, {"beams": len(msg.ranges), "count": 0,
                                                            "finite": 0})
                s["count"] += 1
                s["finite"] += sum(1 for r in msg.ranges if math.isfinite(r))
    print(json.dumps(out))


if __name__ == "__main__":
    main()
