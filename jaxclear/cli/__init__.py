"""The ``jaxclear`` command line (entry point ``jaxclear.cli:main``).

Layout: ``_main`` (parser, error handling, exit codes), ``_common`` (errors, XLA start-up flag),
``_settings`` (the settings schema and the shared run options), ``_config`` (TOML parsing and
layering), ``_mechanism_config`` (mechanisms from the config file), one file per subcommand
(``_run``); result files are written by ``jaxclear.io``.
"""

from ._main import main as main
