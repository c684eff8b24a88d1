# shapesim-decompose: one thin main.cpp linked against the library (rule in the top Makefile).
PROGRAMS += shapesim-decompose
# Its man page's one line (NAME section; help2man, top Makefile).
SUMMARY.shapesim-decompose := fit each postage stamp with a polar shapelet series
