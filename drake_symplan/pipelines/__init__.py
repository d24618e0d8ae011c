"""Pipelines over the whole stack: `symplan reproduce` (reproduce), `symplan curve`
(learning_curve), the results tables they write (results_tables), and the resumable stage
runner both use (stages)."""
