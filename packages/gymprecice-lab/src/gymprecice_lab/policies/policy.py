"""What a policy is, on disk and in memory: shared by the modules that find, run and ship one.

A shipped policy is a directory ``<name>/`` (see :mod:`gymprecice_lab.policies.shipped`
for where they are looked up)::

    model.zip                 the SB3 model, for evaluation only (no optimizer state)
    model_vecnormalize.pkl    the frozen VecNormalize statistics (when trained --normalize)
    policy.json               what it was trained on and how

``policy.json`` records the training env (name, id), its action space and observation
shape, the keyword arguments that shape what the policy does (``env_kwargs``), the
algorithm and hyperparameters, the training command, timesteps, wall-clock time, source
revision and the SHA-256 of the trained model file, the files' own checksums (checked
when a shipped policy loads) and, when shipped with ``--evaluation RUN``, that
evaluation's result (:mod:`gymprecice_lab.policies.ship` writes it).

These names live apart so that looking a policy up, fitting an env to it and shipping
one can each import them without importing each other.
"""

from __future__ import annotations

import json
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

__all__ = [
    "FORMAT",
    "METADATA_NAME",
    "MODEL_NAME",
    "POLICY_NAME",
    "Policy",
    "PolicyError",
    "read_metadata",
]

METADATA_NAME = "policy.json"
MODEL_NAME = "model.zip"
#: the version of ``policy.json``'s layout
FORMAT = 1
#: What can name a policy: its directory, and a bare ``--policy NAME``.
POLICY_NAME = re.compile(r"^[a-z0-9][a-z0-9._-]*$")


class PolicyError(ValueError):
    """A policy that cannot be found, shipped or run on an env; the message is one line."""


@dataclass
class Policy:
    """A policy to evaluate: its model file and, when known, what it was trained on."""

    model: Path
    #: the shipped name (``None`` for a path)
    name: str | None = None
    #: ``policy.json`` of a shipped policy, or the same fields from a training manifest
    metadata: dict[str, Any] | None = None
    #: a remark for the user (e.g. a training directory's newest checkpoint stands in)
    notes: list[str] = field(default_factory=list)

    @property
    def label(self) -> str:
        return f"policy {self.name!r}" if self.name else f"policy {self.model}"

    @property
    def trained_on(self) -> str | None:
        return (self.metadata or {}).get("env", {}).get("name")

    def describe(self) -> dict[str, Any]:
        """What an evaluation's manifest records about the policy."""
        meta = self.metadata or {}
        return {
            "name": self.name,
            "source": "shipped" if self.name else "path",
            "trained_on": meta.get("env"),
            "env_kwargs": meta.get("env_kwargs"),
            "training_model_sha256": meta.get("training", {}).get("model_sha256"),
        }


def read_metadata(policy_dir: str | os.PathLike[str]) -> dict[str, Any]:
    return json.loads((Path(policy_dir) / METADATA_NAME).read_text())
