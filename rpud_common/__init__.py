"""rpud_common: the plumbing every rpud package shares, and nothing heavy.

Errors and checks (:mod:`.errors`), TOML <-> frozen dataclasses (:mod:`.records`), whole-or-nothing
files and folders (:mod:`.files`), figures without global state (:mod:`.figures`), command lines
(:mod:`.cli`, :mod:`.launch`). Standard library, numpy and (for figures, on first use) matplotlib
only: ``geometry``, ``fem``, ``impact`` and ``results`` all build on it, and it imports none of
them, so the data still flows one way (geometry -> fem -> impact -> results) and ``import impact``
loads no mesh, FE or rendering package.
"""

from .lazy import exports

_WHERE = {
    "errors": ("ParameterError", "is_finite_number", "check_positive", "check_nonnegative", "check_finite", "check_integer",
               "check_range", "check_choice"),
    "records": ("MAX_TOML_BYTES", "MAX_TOML_DEPTH", "load_toml", "toml_section", "dump_toml", "from_mapping",
                "to_mapping", "to_jsonable"),
    "files": ("atomic_output", "atomic_write_text", "json_text", "write_json", "NAME_MAX", "PATH_MAX",
              "check_output_paths", "atomic_folder"),
    "figures": ("subplots", "save_figure", "axes_or_new"),
    "result": ("Result",),
    "cli": ("CliParser", "run_cli", "library_error", "setup_logging", "abandon_native_run", "native_code_running",
            "start_native_worker"),
    "signals": ("Terminated",),
    "provenance": ("__version__", "provenance_record"),
    "formatting": ("plus_minus", "group_thousands"),
}
# loaded on first use: an entry point imports rpud_common.launch (standard library only) before
# anything else, and that must not pull numpy in through this package
_MODULE_OF = {name: mod for mod, names in _WHERE.items() for name in names}
__all__ = list(_MODULE_OF)
__getattr__, __dir__ = exports(__name__, _MODULE_OF)
