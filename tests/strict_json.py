"""Reading JSON as strictly as RFC 8259: the software's files must parse in any reader."""

from __future__ import annotations

import json
from typing import Any


def strict_loads(text: str) -> Any:
    """``json.loads`` that refuses NaN, Infinity and -Infinity, tokens strict JSON lacks."""

    def refuse(token: str) -> Any:
        raise ValueError(f"{token} is not strict JSON")

    return json.loads(text, parse_constant=refuse)
