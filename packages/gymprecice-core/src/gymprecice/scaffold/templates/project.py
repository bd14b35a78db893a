"""The skeleton of a new package around its env: ``pyproject.toml`` (its dependency on
gymprecice-core and its ``gymprecice`` entry point), ``README.md``, ``.gitignore`` and the
module's ``__init__.py``.
"""

from __future__ import annotations

__all__ = ["GITIGNORE", "INIT", "PYPROJECT", "README"]

PYPROJECT = """\
# A gymprecice environment package: it reaches gymprecice through its public hooks (the
# entry point below) and its public API (gymprecice.core.Adapter, gymprecice.card.EnvCard).
[build-system]
requires = ["setuptools>=64"]
build-backend = "setuptools.build_meta"

[project]
name = "{{dist}}"
version = "0.1.0"
description = "{{description_sentence}}: a gymprecice environment"
readme = "README.md"
requires-python = ">=3.10"{{plugin_dependency_note}}
dependencies = [{{dependencies}}]

[project.optional-dependencies]
test = ["pytest>=7"]

# gymprecice loads this module on `import gymprecice`: its
# gymprecice_register_environments hook registers {{env_id}} and its lab card.
[project.entry-points.gymprecice]
{{dist}} = "{{module}}.plugin"

# The id, declared in the metadata too: `import gymprecice` registers it before it loads
# any plugin module, so gymnasium.make knows it whichever module a program imports first.
[project.entry-points."gymprecice.environments"]
"{{env_id}}" = "{{module}}.env:{{class_name}}"

[tool.setuptools.packages.find]
where = ["src"]

# the case: gymprecice-config.json, precice-config.xml and the solver's folder
[tool.setuptools.package-data]
{{module}} = ["case/**/*"]

[tool.pytest.ini_options]
testpaths = ["tests"]
"""

README = """\
# {{dist}}

A gymprecice environment package: it registers `{{env_id}}` (short name `{{dist}}`) with
its lab card through the `gymprecice` entry point.

{{task}}

The controller {{actuation_text}}; it reads {{sensing_text}}. {{solver_text}}

## Install, check, train

```bash
pip install -e ./{{folder}}
gymprecice check {{case_path}}
gymprecice train {{env_id}} --double --timesteps 80
pytest {{folder}}/tests
```

`--double` (the env's `double=True`) runs {{double_readme}} (`{{stand_in_path}}`) through
gymprecice's preCICE test double: no preCICE and no solver needed. Without it the env runs {{real_run_text}}; `gymprecice doctor` says what
this machine lacks.

## What to edit

* `src/{{module}}/env.py`: the environment ({{class_name}}, a `gymprecice.core.Adapter`):
  its spaces, the four user methods (`_get_action`, `_get_observation`, `_get_reward`,
  `_close_external_resources`), the controller's vertices and the metrics in
  `info["metrics"]`.
* `src/{{module}}/plugin.py`: the id and the lab card (what `gymprecice train`,
  `evaluate`, `baseline` and `benchmark` read beyond the Gymnasium API).
* `src/{{module}}/case/`: `gymprecice-config.json`, `precice-config.xml` and the solver's
  folder `{{solver_dir}}/`.{{solver_edit_text}}
* `tests/`: the package's own tests, on the test double.
"""

GITIGNORE = """\
__pycache__/
*.egg-info/
build/
dist/
gymprecice-runs/
runs/
"""

INIT = '''\
"""{{class_name}}-v0: a gymprecice environment package.

``import gymprecice`` registers ``{{env_id}}`` through this package's plugin
(:mod:`{{module}}.plugin`); the env is :class:`{{module}}.env.{{class_name}}`.
"""
'''
