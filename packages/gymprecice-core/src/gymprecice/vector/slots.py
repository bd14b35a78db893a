"""What the pool keeps for each env and each batch, and what one env's step returns.

:class:`Slot` is everything the learner knows about one env across its hosts' lives,
:class:`Batch` the jobs of one batch operation in flight, :class:`Outcome` one answer of
a host and :class:`StepResult` one env's part of a batch step. They are apart from
:mod:`.pool` because the pool's jobs (:mod:`.jobs`), its failure handling
(:mod:`.restarts`) and its driver (:mod:`.driver`) all read them.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Generator
from dataclasses import dataclass, field
from typing import Any

from gymprecice.vector.contract import Host, Reply
from gymprecice.vector.failures import EnvFailure


@dataclass
class StepResult:
    """One env's part of a batch step, same-step autoreset applied.

    When the episode ended (``terminated or truncated``), ``obs``/``info`` belong to the
    next episode's reset and ``final_obs``/``final_info`` to the ended one. ``failure`` is
    set when the episode was cut short by an env failure (then ``truncated`` is true,
    ``reward`` is 0 and ``final_obs`` is the last observation the learner received).
    """

    obs: Any
    reward: float
    terminated: bool
    truncated: bool
    info: dict[str, Any]
    final_obs: Any = None
    final_info: dict[str, Any] | None = None
    failure: EnvFailure | None = None

    @property
    def done(self) -> bool:
        return self.terminated or self.truncated


@dataclass
class Outcome:
    value: Any = None
    failure: EnvFailure | None = None
    #: an exception raised by a called method (the env itself is fine)
    call_error: dict[str, Any] | None = None
    roundtrip: float = 0.0


@dataclass
class Slot:
    """Everything the learner knows about env ``index`` across its workers' lives."""

    index: int
    failure_window: int
    worker: Host | None = None
    run_dir: str | None = None
    last_obs: Any = None
    episode_active: bool = False
    pending_failure: EnvFailure | None = None
    seed: int | None = None
    options: dict[str, Any] | None = None
    episodes: int = 0
    spawns: int = 0
    failures: list[EnvFailure] = field(default_factory=list)
    history: deque[bool] = field(init=False)

    def __post_init__(self) -> None:
        self.history = deque(maxlen=self.failure_window)


Job = Generator[float, Reply, Any]


@dataclass
class Batch:
    jobs: dict[int, Job]
    waiting: dict[int, float] = field(default_factory=dict)
    results: dict[int, Any] = field(default_factory=dict)
