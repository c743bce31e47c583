# parallel::RowExchange, the one path that moves per-item rows between ranks.
gen4d_test(parallel_distribute SOURCES test_parallel_distribute.cpp LIBS gen4d_parallel
           RANKS 1 2 4)
