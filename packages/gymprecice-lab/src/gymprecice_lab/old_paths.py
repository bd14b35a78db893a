"""The lab's module paths of earlier versions, each answered with its module now.

The lab's flat modules moved into wings (``gymprecice_lab.train`` is now
``gymprecice_lab.training.train``). Importing the lab installs a finder for this table
(:func:`gymprecice.old_paths.install`), so an old path is the same module object as its
new one. New code imports the new paths.
"""

#: The lab's old module path -> the module that holds it now (docs/architecture.md).
MOVED: dict[str, str] = {
    "gymprecice_lab.benchmark": "gymprecice_lab.benchmarking.command",
    "gymprecice_lab.benchmark_argv": "gymprecice_lab.benchmarking.argv",
    "gymprecice_lab.benchmark_checks": "gymprecice_lab.benchmarking.checks",
    "gymprecice_lab.benchmark_dispatch": "gymprecice_lab.benchmarking.dispatch",
    "gymprecice_lab.benchmark_plots": "gymprecice_lab.benchmarking.plots",
    "gymprecice_lab.benchmark_scores": "gymprecice_lab.benchmarking.scores",
    "gymprecice_lab.benchmark_settings": "gymprecice_lab.benchmarking.settings",
    "gymprecice_lab.benchmark_stats": "gymprecice_lab.benchmarking.stats",
    "gymprecice_lab.benchmark_tables": "gymprecice_lab.benchmarking.tables",
    "gymprecice_lab.benchmark_training": "gymprecice_lab.benchmarking.seed_training",
    "gymprecice_lab.callbacks": "gymprecice_lab.training.callbacks",
    "gymprecice_lab.command_runs": "gymprecice_lab.common.command_runs",
    "gymprecice_lab.compare": "gymprecice_lab.rollouts.compare",
    "gymprecice_lab.env_kwargs": "gymprecice_lab.common.constructor_kwargs",
    "gymprecice_lab.envs": "gymprecice_lab.common.wrapped_env",
    "gymprecice_lab.evaluate": "gymprecice_lab.rollouts.evaluate",
    "gymprecice_lab.evaluation_callback": "gymprecice_lab.training.validation",
    "gymprecice_lab.feedback": "gymprecice_lab.rollouts.feedback",
    "gymprecice_lab.hyperparams": "gymprecice_lab.training.hyperparams",
    "gymprecice_lab.kept_model": "gymprecice_lab.common.kept_model",
    "gymprecice_lab.lab_env": "gymprecice_lab.common.registered_env",
    "gymprecice_lab.learner": "gymprecice_lab.training.learner",
    "gymprecice_lab.manifest": "gymprecice_lab.common.manifest",
    "gymprecice_lab.options": "gymprecice_lab.cli.options",
    "gymprecice_lab.overlap": "gymprecice_lab.training.overlap",
    "gymprecice_lab.plots": "gymprecice_lab.rollouts.plots",
    "gymprecice_lab.policy_env": "gymprecice_lab.policies.fitted_env",
    "gymprecice_lab.policy_format": "gymprecice_lab.policies.policy",
    "gymprecice_lab.prerun_progress": "gymprecice_lab.training.prerun_progress",
    "gymprecice_lab.remote_commands": "gymprecice_lab.benchmarking.remote_commands",
    "gymprecice_lab.requirements": "gymprecice_lab.common.requirements",
    "gymprecice_lab.shared": "gymprecice_lab.training.shared_policy",
    "gymprecice_lab.ship_policy": "gymprecice_lab.policies.ship",
    "gymprecice_lab.shipped_policies": "gymprecice_lab.policies.shipped",
    "gymprecice_lab.slim_model": "gymprecice_lab.policies.slim_model",
    "gymprecice_lab.starts": "gymprecice_lab.common.starts",
    "gymprecice_lab.sweep": "gymprecice_lab.rollouts.sweep",
    "gymprecice_lab.time_to_floor": "gymprecice_lab.benchmarking.time_to_floor",
    "gymprecice_lab.train": "gymprecice_lab.training.train",
    "gymprecice_lab.train_manifest": "gymprecice_lab.training.segments",
    "gymprecice_lab.training_envs": "gymprecice_lab.training.vector_env",
    "gymprecice_lab.training_log": "gymprecice_lab.training.logger",
    "gymprecice_lab.training_loop": "gymprecice_lab.training.loop",
    "gymprecice_lab.tune": "gymprecice_lab.training.tune",
    "gymprecice_lab.tune_spaces": "gymprecice_lab.training.tune_spaces",
    "gymprecice_lab.video": "gymprecice_lab.rollouts.video",
    "gymprecice_lab.wrapping": "gymprecice_lab.common.wrapping",
}
