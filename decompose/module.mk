# shapesim-decompose: one thin main.cpp linked against the library (rule in the top Makefile).
PROGRAMS += shapesim-decompose
