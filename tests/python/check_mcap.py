"""Independent check of a tensorscout run log with the PyPI `mcap` reader.

Usage: check_mcap.py LOG.mcap EXPECTED_COUNTS_JSON
Decodes every message (JSON, schema encoding `jsonschema`), checks schema names, and compares the
per-topic counts with EXPECTED_COUNTS_JSON (what `tensorscout replay --json` reports as
`messages`). Prints the counts as JSON; exits 1 on any mismatch.
"""

import base64
import json
import sys

from mcap.reader import make_reader

SCHEMAS = {
    "/robot/pose": "foxglove.PoseInFrame",
    "/tf": "foxglove.FrameTransforms",
    "/robot/footprint": "foxglove.SceneUpdate",
    "/robot/trajectory": "foxglove.SceneUpdate",
    "/scene": "foxglove.SceneUpdate",
    "/camera/depth": "foxglove.RawImage",
    "/camera/calibration": "foxglove.CameraCalibration",
    "/map/grid": "foxglove.Grid",
    "/field/tensor": "foxglove.Grid",
    "/field/degenerate": "foxglove.SceneUpdate",
    "/field/topology": "foxglove.SceneUpdate",
    "/plan/frontiers": "foxglove.SceneUpdate",
    "/plan/path": "foxglove.SceneUpdate",
    "/plan/tour": "foxglove.SceneUpdate",
    "/metrics": "tensorscout.Metrics",
}


def main() -> int:
    path, expected = sys.argv[1], json.loads(sys.argv[2])
    counts = {}
    with open(path, "rb") as f:
        reader = make_reader(f)
        for schema, channel, message in reader.iter_messages():
            assert schema.encoding == "jsonschema", schema.encoding
            assert channel.message_encoding == "json", channel.message_encoding
            assert SCHEMAS.get(channel.topic) == schema.name, (channel.topic, schema.name)
            msg = json.loads(message.data)
            if channel.topic == "/camera/depth":
                data = base64.b64decode(msg["data"])
                assert msg["encoding"] == "16UC1", msg["encoding"]
                assert len(data) == msg["width"] * msg["height"] * 2
            if channel.topic == "/map/grid":
                data = base64.b64decode(msg["data"])
                assert len(data) % msg["row_stride"] == 0
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
        summary = reader.get_summary()
        stats = summary.statistics if summary else None
    print(json.dumps(counts, sort_keys=True))
    if counts != expected:
        print(f"counts differ: python {counts} vs tensorscout {expected}", file=sys.stderr)
        return 1
    if stats is None or stats.message_count != sum(counts.values()):
        print("summary statistics missing or different", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
