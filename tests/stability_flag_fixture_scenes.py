"""A demo scene with ``Scene.stability = False`` (tests/test_scene_no_stability.py): the
``stretched-bratu`` scene of problems/scenes_demo.py, same run and problem_factory, declared to
have no linear-stability operator."""

import dataclasses

from problems.scenes_demo import SCENES as DEMO

SCENES = {"stretched-bratu-nostab": dataclasses.replace(DEMO["stretched-bratu"], name="stretched-bratu-nostab",
                                                        stability=False)}
