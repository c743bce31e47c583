# Tests of the chart renderer in src/io (Plot): sizes, placement, text, colour scale, failures.
gen4d_test(plot SOURCES test_plot.cpp LIBS gen4d_io RANKS 1)
