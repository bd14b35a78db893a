"""The case files every kind shares: the preCICE configuration that couples the
controller to the solver, and the README of the empty solver folder a kind the scaffold
knows nothing about gets.
"""

from __future__ import annotations

__all__ = ["PRECICE_CONFIG", "SOLVER_README"]

PRECICE_CONFIG = """\
<?xml version="1.0" encoding="UTF-8" ?>
<!-- The controller writes "{{write}}" at its actuators and reads "{{read}}" at its
     sensors; participant "{{participant}}" ({{solver_dir}}/) maps both to its own mesh. -->
<precice-configuration>
  <data:{{write_type}} name="{{write}}" />
  <data:{{read_type}} name="{{read}}" />

  <mesh name="Controller-Mesh-actuator" dimensions="2"><use-data name="{{write}}" /></mesh>
  <mesh name="Controller-Mesh-sensor" dimensions="2"><use-data name="{{read}}" /></mesh>
  <mesh name="{{mesh}}" dimensions="2">
    <use-data name="{{write}}" />
    <use-data name="{{read}}" />
  </mesh>

  <!-- gymprecice plays "Controller" (controller.participant in gymprecice-config.json):
       one mesh per interface, "actuator" and "sensor" -->
  <participant name="Controller">
    <provide-mesh name="Controller-Mesh-actuator" />
    <provide-mesh name="Controller-Mesh-sensor" />
    <write-data name="{{write}}" mesh="Controller-Mesh-actuator" />
    <read-data name="{{read}}" mesh="Controller-Mesh-sensor" />
  </participant>

  <participant name="{{participant}}">
    <provide-mesh name="{{mesh}}" />
    <receive-mesh name="Controller-Mesh-actuator" from="Controller" />
    <receive-mesh name="Controller-Mesh-sensor" from="Controller" />
    <read-data name="{{write}}" mesh="{{mesh}}" />
    <write-data name="{{read}}" mesh="{{mesh}}" />
    <mapping:nearest-neighbor direction="read" from="Controller-Mesh-actuator"
        to="{{mesh}}" constraint="{{actuation_constraint}}" />
    <mapping:nearest-neighbor direction="write" from="{{mesh}}"
        to="Controller-Mesh-sensor" constraint="consistent" />
  </participant>

  <!-- exchange-directory is rewritten per env, so parallel envs never collide -->
  <m2n:sockets acceptor="Controller" connector="{{participant}}" exchange-directory="" />

  <coupling-scheme:parallel-explicit>
    <participants first="Controller" second="{{participant}}" />
    <max-time value="{{end_time}}" />
    <time-window-size value="{{window}}" />
    <!-- initialize: the solver's first window sees the actuators' state at reset -->
    <exchange data="{{write}}" mesh="Controller-Mesh-actuator" from="Controller"
        to="{{participant}}" initialize="true" />
    <exchange data="{{read}}" mesh="Controller-Mesh-sensor" from="{{participant}}"
        to="Controller" />
  </coupling-scheme:parallel-explicit>
</precice-configuration>
"""

SOLVER_README = """\
# The solver's case

Solver kind `{{kind}}` comes from the plugin `{{plugin}}`{{plugin_distribution}}. Put the
files its plugin reads here: this folder is the solver's `path` in
`../gymprecice-config.json`, copied into every env's run directory. The solver is
participant `{{participant}}` of `../precice-config.xml`: it provides the mesh `{{mesh}}`,
reads `{{write}}` and writes `{{read}}` there.

`gymprecice check` on the case folder says what the plugin misses; the plugin's own
documentation says which options it takes (`options` of the solver in
`gymprecice-config.json`).
"""
