"""Foxglove WebSocket clients that subscribe and then never read: each of N connections reads the
server's info and advertised channels, subscribes to one topic, and from then on reads nothing
(websockets' receive queue of one message fills, then the transport stops reading). Prints
"subscribed" once all are, then sleeps until killed."""
import asyncio
import json
import sys

import websockets


async def stall(url, topic, timeout):
    ws = await websockets.connect(url, subprotocols=["foxglove.sdk.v1"], max_size=None, max_queue=1)
    channels = {}
    while topic not in channels:
        msg = json.loads(await asyncio.wait_for(ws.recv(), timeout))
        if msg["op"] == "advertise":
            for c in msg["channels"]:
                channels[c["topic"]] = c["id"]
    await ws.send(json.dumps({"op": "subscribe", "subscriptions": [{"id": 1, "channelId": channels[topic]}]}))
    return ws


async def main(url, n, topic, timeout):
    clients = [await stall(url, topic, timeout) for _ in range(n)]
    print("subscribed", flush=True)
    await asyncio.sleep(3600)
    del clients


if __name__ == "__main__":
    asyncio.run(main(sys.argv[1], int(sys.argv[2]), sys.argv[3], float(sys.argv[4])))
