"""Test helper (tests/test_approach1.py): on PYTHONPATH with DAMPERTWIN_TRACE
set, every Python process started under `dvc repro` records the files it
opens (audit 'open' events, plus pyarrow's Parquet readers, which open files
in C++). A stage script (argv[0] under stages/) names the stage; its child
processes (joblib workers) inherit the name through the environment."""

import os
import sys

_dir = os.environ.get("DAMPERTWIN_TRACE")
if _dir:
    _argv0 = sys.argv[0] if sys.argv else ""
    if "DAMPERTWIN_TRACE_STAGE" not in os.environ and os.path.basename(os.path.dirname(_argv0)) == "stages":
        os.environ["DAMPERTWIN_TRACE_STAGE"] = " ".join([os.path.basename(_argv0), *sys.argv[1:]])
    _stage = os.environ.get("DAMPERTWIN_TRACE_STAGE")
    if _stage:
        _log = open(os.path.join(_dir, f"{os.getpid()}.log"), "a", buffering=1)
        _seen = set()
        _WRITE = os.O_WRONLY | os.O_RDWR | os.O_CREAT | os.O_APPEND

        def _record(p, mode):
            if not isinstance(p, (str, bytes, os.PathLike)):
                return
            key = (os.path.abspath(os.fsdecode(p)), mode)
            if key not in _seen:
                _seen.add(key)
                _log.write(f"{_stage}\t{mode}\t{key[0]}\n")

        def _hook(event, args):
            if event != "open" or not args:
                return
            mode = args[1] if len(args) > 1 else None
            if not isinstance(mode, str):
                flags = args[2] if len(args) > 2 and isinstance(args[2], int) else 0
                mode = "w" if flags & _WRITE else "r"
            _record(args[0], "w" if any(c in mode for c in "wax+") else "r")

        sys.addaudithook(_hook)

        import importlib.abc
        import importlib.machinery

        class _PatchParquet(importlib.abc.MetaPathFinder):
            def find_spec(self, name, path, target=None):
                if name != "pyarrow.parquet":
                    return None
                spec = importlib.machinery.PathFinder.find_spec(name, path)
                if spec is None:
                    return None
                exec_module = spec.loader.exec_module

                def exec_and_patch(module):
                    exec_module(module)
                    for fn in ("read_table", "read_schema", "read_metadata"):
                        orig = getattr(module, fn)

                        def wrapped(source, *a, _orig=orig, **k):
                            _record(source, "r")
                            return _orig(source, *a, **k)

                        setattr(module, fn, wrapped)
                    init = module.ParquetFile.__init__

                    def pf_init(self, source, *a, _init=init, **k):
                        _record(source, "r")
                        return _init(self, source, *a, **k)

                    module.ParquetFile.__init__ = pf_init

                spec.loader.exec_module = exec_and_patch
                return spec

        sys.meta_path.insert(0, _PatchParquet())
