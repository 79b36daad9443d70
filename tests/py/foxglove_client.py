"""A Foxglove WebSocket client written from the protocol's description, with PyPI `websockets`
(subprotocol foxglove.sdk.v1, the Foxglove WebSocket protocol under its current name): reads the server's info and advertised channels, subscribes
to every channel, prints "subscribed", then decodes the messages it gets with
mcap-ros2-support's ROS 2 decoder (independent of sqscan's encoder) until it has a cloud and a
detection array, and prints what it saw as one JSON object."""
import asyncio
import json
import math
import struct
import sys

import websockets
from mcap_ros2._dynamic import generate_dynamic


async def main(url, timeout):
    out = {"server_info": None, "channels": [], "points": None, "detections": [], "joint_states": 0}
    async with websockets.connect(url, subprotocols=["foxglove.sdk.v1"], max_size=None) as ws:
        out["subprotocol"] = ws.subprotocol
        channels = {}
        while out["server_info"] is None or len(channels) < 3:
            msg = json.loads(await asyncio.wait_for(ws.recv(), timeout))
            if msg["op"] == "serverInfo":
                out["server_info"] = msg
            elif msg["op"] == "advertise":
                for c in msg["channels"]:
                    channels[c["id"]] = c
        out["channels"] = sorted(
            ({"topic": c["topic"], "encoding": c["encoding"], "schemaName": c["schemaName"],
              "schemaEncoding": c.get("schemaEncoding")} for c in channels.values()),
            key=lambda c: c["topic"])
        subs = {}
        decoders = {}
        for i, c in enumerate(channels.values(), start=1):
            subs[i] = c
            decoders[i] = generate_dynamic(c["schemaName"], c["schema"])[c["schemaName"]]
        await ws.send(json.dumps({"op": "subscribe", "subscriptions": [{"id": i, "channelId": c["id"]} for i, c in subs.items()]}))
        print("subscribed", flush=True)
        while out["points"] is None or not out["detections"]:
            data = await asyncio.wait_for(ws.recv(), timeout)
            if isinstance(data, str):
                continue
            assert data[0] == 0x01, f"opcode {data[0]}"
            sub, log_time = struct.unpack_from("<IQ", data, 1)
            msg = decoders[sub](data[13:])
            topic = subs[sub]["topic"]
            if topic == "/sqscan/points":
                step = msg.point_step
                raw = bytes(msg.data)
                pts = [struct.unpack_from("<fff", raw, k * step) for k in range(msg.height * msg.width)]
                out["points"] = {
                    "frame": msg.header.frame_id, "height": msg.height, "width": msg.width,
                    "fields": [f.name for f in msg.fields], "is_dense": msg.is_dense,
                    "finite": sum(1 for p in pts if not math.isnan(p[0])),
                    "first_finite": next([float(v) for v in p] for p in pts if not math.isnan(p[0])),
                    "log_time": log_time,
                }
            elif topic == "/sqscan/detections":
                out["detections"].append([
                    {"class_id": d.results[0].hypothesis.class_id, "score": d.results[0].hypothesis.score,
                     "position": [d.results[0].pose.pose.position.x, d.results[0].pose.pose.position.y,
                                  d.results[0].pose.pose.position.z]}
                    for d in msg.detections])
            elif topic == "/sqscan/joint_states":
                out["joint_states"] += 1
    print(json.dumps(out), flush=True)


if __name__ == "__main__":
    asyncio.run(main(sys.argv[1], float(sys.argv[2])))
