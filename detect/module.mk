# shapesim-detect: one thin main.cpp linked against the library (rule in the top Makefile).
PROGRAMS += shapesim-detect
# Its man page's one line (NAME section; help2man, top Makefile).
SUMMARY.shapesim-detect := find the objects of a deep image, measure them and cut their postage stamps
