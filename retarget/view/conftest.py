"""pytest's doctest collection: skip the modules that draw when the viz extra is not installed."""

import importlib.util

_NEEDS = {"rerun_log.py": "rerun", "live.py": "rerun", "sinks.py": "rerun", "plot.py": "matplotlib",
          "sheet.py": "matplotlib"}  # fmt: skip
collect_ignore = [name for name, module in _NEEDS.items() if importlib.util.find_spec(module) is None]
