"""drake_symplan_configs: the experiments as data (data recipes, scales, Table I's training
settings), YAML files read through drake_symplan.typed_yaml.

Shipped as package data so that an installed package finds them;
`drake_symplan.typed_yaml.shipped_config(name)` locates them (the checkout's first).
"""
