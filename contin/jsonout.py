"""Strict JSON documents for the CLI (``--json``) and for HDF5 provenance attributes.

RFC 8259 has no NaN or infinity, so :func:`to_jsonable` maps NaN to ``null`` and +-inf to the
strings ``"inf"`` / ``"-inf"`` (``float("inf")`` reads them back; a parameter such as the Froude
number may legitimately be infinite).  numpy scalars and arrays become Python numbers and lists,
tuples become lists, dataclasses become dicts.
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Mapping
from typing import Any

from contin.branch import Branch, SpecialPoint


def to_jsonable(obj: Any) -> Any:
    """A copy of ``obj`` that :func:`json.dumps` accepts with ``allow_nan=False``."""
    if obj is None or isinstance(obj, (bool, str)):
        return obj
    if isinstance(obj, int):
        return int(obj)
    if isinstance(obj, float):
        if math.isnan(obj):
            return None
        if math.isinf(obj):
            return "inf" if obj > 0 else "-inf"
        return float(obj)
    # numpy without importing it at module level (keeps `contin --help` fast)
    kind = getattr(getattr(obj, "dtype", None), "kind", None)
    if kind is not None:
        if getattr(obj, "ndim", 0) == 0:
            item = obj.item()
            if isinstance(item, complex):
                return {"re": to_jsonable(item.real), "im": to_jsonable(item.imag)}
            if isinstance(item, bytes):
                return item.decode()
            return to_jsonable(item)
        return [to_jsonable(x) for x in obj]
    if isinstance(obj, complex):
        return {"re": to_jsonable(obj.real), "im": to_jsonable(obj.imag)}
    if isinstance(obj, bytes):
        return obj.decode()
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return to_jsonable(dataclasses.asdict(obj))
    if isinstance(obj, Mapping):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple, set, frozenset)):
        return [to_jsonable(x) for x in obj]
    return str(obj)


def dumps(obj: Any, **kw: Any) -> str:
    """Strict JSON text of ``obj`` (see :func:`to_jsonable`)."""
    return json.dumps(to_jsonable(obj), allow_nan=False, **kw)


def from_json_value(value: Any) -> Any:
    """Inverse of the number mapping of :func:`to_jsonable` for scalars: 'inf' -> inf."""
    if value == "inf":
        return math.inf
    if value == "-inf":
        return -math.inf
    if value is None:
        return math.nan
    return value


def branch_summary(branch: Branch) -> dict[str, Any]:
    """``{id, kind, parent, parameter, status, message, closed, n_points}``."""
    return {
        "id": branch.id,
        "kind": branch.kind,
        "parent": branch.parent,
        "parameter": branch.parameter,
        "free": list(branch.free),
        "status": branch.status,
        "message": branch.message,
        "closed": bool(branch.closed),
        "n_points": len(branch),
    }


def special_point_summary(sp: SpecialPoint, branch_id: str) -> dict[str, Any]:
    """``{type, label, name, branch, index, params, phi, bracket, converged, note, data}``
    (data: e.g. omega and l1 of an HB, value of a UZ; ``{}`` for other points)."""
    return {
        "type": sp.type,
        "label": sp.name,
        "branch": branch_id,
        "index": int(sp.index),
        "params": dict(sp.params),
        "phi": sp.order_parameter,
        "bracket": list(sp.bracket),
        "converged": bool(sp.converged),
        "note": sp.note,
        "data": dict(sp.data),
    }


def run_document(
    *,
    scene: str,
    parameters: Mapping[str, Any],
    discretization: Mapping[str, Any],
    branches: list[Branch],
    notes: list[str] | tuple[str, ...] = (),
    extra: Mapping[str, Any] | None = None,
    **more: Any,
) -> dict[str, Any]:
    """The JSON document printed by ``contin trace --json`` (already strict-JSON-able)."""
    doc = {
        "scene": scene,
        "parameters": dict(parameters),
        "discretization": dict(discretization),
        "notes": list(notes),
        "extra": dict(extra or {}),
        "branches": [branch_summary(b) for b in branches],
        "special_points": [special_point_summary(sp, b.id) for b in branches for sp in b.special_points],
        **more,
    }
    return to_jsonable(doc)
