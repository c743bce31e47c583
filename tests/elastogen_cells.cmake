# Cells with a spacing per axis, point masses and pre-loads in ElastoGen and the Newton
# reference: [h, h, h] against h, a thin cantilever against Euler-Bernoulli, a point mass's
# weight, a pluck, a misplaced point mass, and the bits at 1 and 2 ranks.
gen4d_test(elastogen_cells SOURCES test_elastogen_cells.cpp LIBS gen4d_elastogen RANKS 1 2)
