"""
The engine: TranslatorSolver and the parts that carry a solve from a wrench to a result.

solver is the face (input checks, the time limit, the public API); engine owns the solve
state (last solution, factorization, verdicts, refinement memory) and the steps of a solve;
continuation follows the load path; correctors, multiple_shooting (lifted Newton for cold
solves) and path_following iterate; refinement is the refinement policy; branch gives the
stability verdict on the stable branch; warm_fast_path is the compiled warm path (one warm
solve, or a run of batch rows, in one call); batch and result are the result types; verify
re-checks a result independently; wrench_estimation hands the translator, as callables, to
cdr_translator.estimation as its forward model.
"""
