"""OpenSCENARIO 1.x on the env: scenario-based testing of the function under test.

``gym.make("ALDMHighway-v0", config={"scenario": {"xosc": path, "parameters": {...}}})``
plays a concrete scenario: its map (``RoadNetwork/LogicFile``) is the road, its
objects are the traffic, moved exactly as its storyboard says, and the ego is the
function under test, perceiving its lanes through the line sensor and the configured
detector (docs/scenarios.md).

Modules:

- :mod:`~aldm_gym.scenario.expressions`, :mod:`~aldm_gym.scenario.declarations`,
  :mod:`~aldm_gym.scenario.distributions`: ``${...}`` expressions, parameter
  declarations with their constraints, and parameter-variation files.
- :mod:`~aldm_gym.scenario.reader`: the file into entities, ``Init`` and storyboard.
- :mod:`~aldm_gym.scenario.storyboard`: the element life cycle and triggers.
- :mod:`~aldm_gym.scenario.conditions`, :mod:`~aldm_gym.scenario.actions`,
  :mod:`~aldm_gym.scenario.positions`: what the elements do.
- :mod:`~aldm_gym.scenario.world`: the entities on the map and how scripted ones move.
- :mod:`~aldm_gym.scenario.runner`: one run on the env's road.

The UN R157 criteria and suites of runs are the harness above the env
(:mod:`aldm_gym.harness`).
"""

from aldm_gym.scenario.reader import Scenario, read_scenario
from aldm_gym.scenario.runner import ScenarioRunner, choose_ego
from aldm_gym.scenario.settings import ScenarioConfig

__all__ = ["Scenario", "ScenarioConfig", "ScenarioRunner", "choose_ego", "read_scenario"]
