#!/usr/bin/env python3
"""Validates JSON or TOML documents against one of furbake's JSON Schemas (docs/schemas/).

    python3 tools/check_schema.py docs/schemas/bake-report.schema.json report.json [more.json ...]
    python3 tools/check_schema.py docs/schemas/scene.schema.json fixtures/scenes/*.toml

A `.toml` file is read with Python's tomllib (3.11+) and validated as the JSON it maps to.

Prints one line per violation (`file: path: message`) and exits 1 when any document breaks its
schema, 2 when the schema itself is not a valid draft 2020-12 schema or a file cannot be read.
Needs the `jsonschema` Python package (Debian: python3-jsonschema; `make deps` installs it).
"""

import json
import sys
import tomllib

import jsonschema


def main(argv):
    if len(argv) < 3:
        print(__doc__.strip(), file=sys.stderr)
        return 2
    try:
        with open(argv[1], encoding="utf-8") as f:
            schema = json.load(f)
        jsonschema.Draft202012Validator.check_schema(schema)
    except (OSError, ValueError, jsonschema.SchemaError) as e:
        print(f"{argv[1]}: {e}", file=sys.stderr)
        return 2
    validator = jsonschema.Draft202012Validator(schema)
    bad = 0
    for path in argv[2:]:
        try:
            if path.endswith(".toml"):
                with open(path, "rb") as f:
                    doc = tomllib.load(f)
            else:
                with open(path, encoding="utf-8") as f:
                    doc = json.load(f)
        except (OSError, ValueError) as e:
            print(f"{path}: {e}", file=sys.stderr)
            return 2
        for error in sorted(validator.iter_errors(doc), key=lambda e: list(e.absolute_path)):
            where = "/".join(str(p) for p in error.absolute_path) or "(root)"
            print(f"{path}: {where}: {error.message}")
            bad += 1
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
