"""The key of a job: the file-name stem of its record and of its image folder.

A key is readable (model, method label, budget, shading), the same in every run (a hash
of text, never Python's per-process ``hash``), and different for different jobs. Each
part is used as it is when it is *plain* (a catalog model's name, a file name with no
folder, a method and parameters of letters, digits, ``_``, ``.`` and ``-``): those are
the keys records always had, so ``--resume`` finds the records of older run folders. A
part that is not plain gets a short hash of its exact value, because its slug alone
could merge two jobs: ``A/mesh.obj`` and ``B/mesh.obj`` both slug to ``mesh``; the
parameter values ``a b``, ``a/b`` and ``a-b`` all slug to ``a-b``; and protocol settings
other than the shading do not show in the key at all.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
from pathlib import Path

from metrics.protocol import Protocol

__all__ = ["job_key", "legacy_job_key"]

#: A name that is its own slug and cannot run into the separators around it in a key.
_PLAIN = re.compile(r"[A-Za-z0-9_.](?:[A-Za-z0-9_.-]*[A-Za-z0-9_.])?")
#: A parameter name that cannot run into ``=``, ``,`` or the method's name.
_PLAIN_NAME = re.compile(r"[A-Za-z0-9_]+")


def job_key(model: str, method: str, label: str, params: dict, target_faces: int,
            protocol: Protocol) -> str:
    """``model__label__target__shading-pVERSION``, each part hashed where not plain."""
    settings = {k: v for k, v in protocol.as_dict().items()
                if k not in ("shading", "specular", "version") and v != getattr(Protocol(), k)}
    return (f"{_model_part(model)}__{_method_part(method, label, params)}__{target_faces}"
            f"__{protocol.shading}{'-spec' if protocol.specular else ''}-p{protocol.version}"
            f"{'-' + _short_hash(settings) if settings else ''}")


def legacy_job_key(model: str, label: str, target_faces: int, protocol: Protocol) -> str:
    """The key records had before parts were hashed (a path's bare stem, the label's
    slug): where a report of an older run folder finds its images."""
    stem = _slug(Path(model).stem if os.sep in model else model)
    return (f"{stem}__{_slug(label)}__{target_faces}"
            f"__{protocol.shading}{'-spec' if protocol.specular else ''}-p{protocol.version}")


def _model_part(model: str) -> str:
    """A catalog name or a plain file name as it is; any other path as its stem and a
    hash of the normalised path (so ``./A/x.obj`` and ``A/x.obj`` are one job)."""
    if "/" in model or os.sep in model:
        model = os.path.normpath(model)
    if _plain(model):
        return model
    return f"{_slug(Path(model).stem) or 'model'}-{_short_hash(model)}"


def _method_part(method: str, label: str, params: dict) -> str:
    """The label's slug, with a hash of the method and parameters unless all are plain."""
    values = sorted((str(k), _text(v)) for k, v in params.items())
    if _plain(method) and all(_plain(k, _PLAIN_NAME) and _plain(v) for k, v in values):
        return _slug(label)
    return f"{_slug(label)}-{_short_hash([method, values])}"


def _plain(text: str, pattern: re.Pattern = _PLAIN) -> bool:
    return bool(pattern.fullmatch(text)) and "__" not in text


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.=,-]+", "-", text).strip("-")


def _text(value) -> str:
    """A parameter value as its label shows it (booleans lower case)."""
    return str(value).lower() if isinstance(value, bool) else str(value)


def _short_hash(value) -> str:
    text = json.dumps(value, sort_keys=True, ensure_ascii=True)
    return hashlib.sha256(text.encode()).hexdigest()[:8]
