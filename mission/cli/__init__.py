"""Command-line entry points. Each subcommand is a module ``mission.cli.<name>`` with
``add_arguments`` and ``run``; modules keep their heavy imports inside ``run`` so ``rfsl --help``
stays fast."""
