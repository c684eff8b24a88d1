# shapesim-sample: one thin main.cpp linked against the library (rule in the top Makefile).
PROGRAMS += shapesim-sample
# Its man page's one line (NAME section; help2man, top Makefile).
SUMMARY.shapesim-sample := draw new galaxies from the morphology model
