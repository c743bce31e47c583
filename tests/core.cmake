gen4d_test(deck SOURCES test_deck.cpp test_deck_errors.cpp LIBS gen4d_core RANKS 1)
