"""Independent client of a tensorscout live view (Foxglove WebSocket protocol, foxglove.websocket.v1).

Usage: check_live.py ws://HOST:PORT TOPIC [TOPIC ...]
Connects with the PyPI `websockets` client offering the subprotocol, reads `serverInfo` and
`advertise` (which must offer the `time` capability), subscribes to TOPIC..., and reads binary
`messageData` and `time` frames (the clock must go forward) until the server closes. Every
message received is decoded as JSON and validated with `jsonschema` against the schema its channel
advertised. Prints a JSON object {topic: {"messages": n, "first_ns": t, "last_ns": t}} and exits 1
if a topic was not advertised, a message does not validate, or a subscribed topic got no message.
"""

import asyncio
import json
import struct
import sys

import jsonschema
import websockets

SUBPROTOCOL = "foxglove.websocket.v1"


async def run(url: str, topics: list[str]) -> int:
    async with websockets.connect(
        url, subprotocols=[SUBPROTOCOL], max_size=None, open_timeout=10
    ) as ws:
        assert ws.subprotocol == SUBPROTOCOL, ws.subprotocol
        info = json.loads(await ws.recv())
        assert info["op"] == "serverInfo", info
        assert "time" in info["capabilities"], info
        advertise = json.loads(await ws.recv())
        assert advertise["op"] == "advertise", advertise
        channels = {c["topic"]: c for c in advertise["channels"]}
        missing = [t for t in topics if t not in channels]
        if missing:
            print(f"not advertised: {missing}", file=sys.stderr)
            return 1
        validators = {}
        subscriptions = []
        for sub_id, topic in enumerate(topics):
            c = channels[topic]
            assert c["encoding"] == "json", c
            assert c["schemaEncoding"] == "jsonschema", c
            schema = json.loads(c["schema"])
            jsonschema.Draft7Validator.check_schema(schema)
            validators[sub_id] = (topic, jsonschema.Draft7Validator(schema))
            subscriptions.append({"id": sub_id, "channelId": c["id"]})
        await ws.send(json.dumps({"op": "subscribe", "subscriptions": subscriptions}))
        seen = {}
        clock = -1
        try:
            async for frame in ws:
                if isinstance(frame, str):
                    msg = json.loads(frame)
                    assert msg["op"] in ("status", "advertise", "unadvertise"), msg
                    continue
                if frame[0] == 0x02:  # time: the server's (simulated) clock
                    (now,) = struct.unpack_from("<Q", frame, 1)
                    assert now > clock, (now, clock)
                    clock = now
                    continue
                opcode, sub_id, stamp = struct.unpack_from("<BIQ", frame)
                assert opcode == 0x01, opcode
                topic, validator = validators[sub_id]
                message = json.loads(frame[13:])
                errors = list(validator.iter_errors(message))
                if errors:
                    print(f"{topic} at {stamp} ns: {errors[0].message}", file=sys.stderr)
                    return 1
                s = seen.setdefault(topic, {"messages": 0, "first_ns": stamp, "last_ns": stamp})
                s["messages"] += 1
                s["last_ns"] = max(s["last_ns"], stamp)
        except websockets.ConnectionClosedError:
            pass
    print(json.dumps(seen, sort_keys=True))
    silent = [t for t in topics if t not in seen]
    if silent:
        print(f"no message on {silent}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(asyncio.run(run(sys.argv[1], sys.argv[2:])))
