"""Reading a JSON object from a user's file, with one clear error per failure."""

from __future__ import annotations

import json
from pathlib import Path


def read_json_object(path: Path, error: type[Exception], missing: str) -> dict:
    """The JSON object in ``path``; raises ``error`` when the file is missing (message
    ``missing``, where ``{path}`` stands for the path), is not JSON or holds no object."""
    try:
        value = json.loads(Path(path).read_text())
    except FileNotFoundError:
        raise error(missing.format(path=path)) from None
    except (json.JSONDecodeError, UnicodeDecodeError) as decode_error:
        raise error(f"{path} is not valid JSON: {decode_error}") from None
    if not isinstance(value, dict):
        raise error(f"{path} must hold a JSON object")
    return value
