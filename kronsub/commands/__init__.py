"""Commands of the command line beyond derive/codegen/simulate, one module per concern;
:mod:`kronsub.cli` registers them on its group."""
