"""
The engine: TranslatorSolver and the parts that carry a solve from a wrench to a result.

solver is the face; continuation follows the load path; correctors, multiple_shooting
(lifted Newton for cold solves), path_following and refinement iterate and refine;
branch gives the stability verdict on the stable branch; lean_rows, warm_rows and
warm_step are the compiled warm path; batch and result are the result types; verify
re-checks a result independently; given_unknowns builds a result at unknowns converged
elsewhere (the robot's coupled Newton); wrench_estimation hands the translator to
cdr_translator.estimation as its forward model.
"""
