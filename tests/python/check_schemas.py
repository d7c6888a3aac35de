"""Checks a tensorscout run log against Foxglove's official JSON schemas.

Usage: check_schemas.py LOG.mcap SCHEMA_DIR
For every channel whose schema name is `foxglove.NAME`: the schema bytes in the log must be exactly
SCHEMA_DIR/NAME.json (the vendored `@foxglove/schemas` 2.1.0 file), and every message on it must
validate against that schema (Python `jsonschema`, the schema's own draft). Stops at the first
difference with a message naming the topic, the message's log time and the failing path. Prints the
number of messages validated per topic as JSON.
"""

import json
import os
import sys

import jsonschema
from mcap.reader import make_reader


def main() -> int:
    path, schema_dir = sys.argv[1], sys.argv[2]
    validators = {}
    counts = {}
    with open(path, "rb") as f:
        reader = make_reader(f)
        for schema, channel, message in reader.iter_messages():
            if not schema.name.startswith("foxglove."):
                continue
            if schema.id not in validators:
                official_path = os.path.join(schema_dir, schema.name[len("foxglove."):] + ".json")
                if not os.path.exists(official_path):
                    print(f"{channel.topic}: no official schema file for {schema.name}", file=sys.stderr)
                    return 1
                with open(official_path, "rb") as o:
                    official = o.read()
                if schema.data != official:
                    print(
                        f"{channel.topic}: schema {schema.name} in the log differs from {official_path}",
                        file=sys.stderr,
                    )
                    return 1
                parsed = json.loads(official)
                cls = jsonschema.validators.validator_for(parsed)
                cls.check_schema(parsed)
                validators[schema.id] = cls(parsed)
            msg = json.loads(message.data)
            errors = sorted(validators[schema.id].iter_errors(msg), key=lambda e: list(e.absolute_path))
            if errors:
                e = errors[0]
                where = "/".join(str(p) for p in e.absolute_path)
                print(
                    f"{channel.topic} at log time {message.log_time} ns: /{where}: {e.message}",
                    file=sys.stderr,
                )
                return 1
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
    print(json.dumps(counts, sort_keys=True))
    return 0


if __name__ == "__main__":
    sys.exit(main())
