"""drake_symplan: a UR10 in Drake learns unary and relational symbols and plans with them."""

__version__ = "0.1.0"
