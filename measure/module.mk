# shapesim-measure: one thin main.cpp linked against the library (rule in the top Makefile).
PROGRAMS += shapesim-measure
# Its man page's one line (NAME section; help2man, top Makefile).
SUMMARY.shapesim-measure := measure the morphology of the galaxies of an image
