"""Reading a JSON object from a user's file, with one clear error per failure."""

from __future__ import annotations

import json
from pathlib import Path


def read_json_object(path: Path, error: type[Exception], missing: str) -> dict:
    """The JSON object in ``path``; raises ``error`` when the file is missing (message
    ``missing``, where ``{path}`` stands for the path), is not JSON or holds no object."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig")  # a byte-order mark is not an error
    except FileNotFoundError:
        raise error(missing.format(path=path)) from None
    except IsADirectoryError:
        raise error(f"{path} is a directory, not a JSON file") from None
    except UnicodeDecodeError:
        raise error(f"{path} is not UTF-8 text") from None
    try:
        value = json.loads(text)
    except json.JSONDecodeError as decode_error:
        raise error(f"{path} is not valid JSON: {decode_error}") from None
    except RecursionError:
        raise error(f"{path} is nested too deeply to be a JSON file of ours") from None
    if not isinstance(value, dict):
        raise error(f"{path} must hold a JSON object")
    return value
