"""The symbolic layer: symbols as atoms, lifted operators learned from them, PDDL; no Drake.

`structs` (Atom, LiftedOperator, Step, Reposition, Task: the types everything above
speaks), `states` (a read-out as atoms), `effect_operators` (the effect-first learner with
reliabilities) and `operators` (the paper's learner, with `canonical` object orders),
`pddl` (domain and problem writers, a positive-STRIPS reader), `bundle` (a trained model
and its operators as one directory), `report` (what `symplan operators` writes).
Learning's symbols come in as arrays (SymbolDataset); planning's back-ends read the PDDL.
"""
