"""The commands of the command line, one module per command; what they share is in
:mod:`~kronsub.commands.common`. :mod:`kronsub.cli` registers them on its group."""
