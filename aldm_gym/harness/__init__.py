"""The test harness above the env: UN R157 criteria of a scenario run
(:mod:`~aldm_gym.harness.criteria`) and suites of runs (:mod:`~aldm_gym.harness.suite`),
with any function under test (:mod:`aldm_gym.function`)."""
