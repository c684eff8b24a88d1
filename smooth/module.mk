# shapesim-smooth: one thin main.cpp linked against the library (rule in the top Makefile).
PROGRAMS += shapesim-smooth
# Its man page's one line (NAME section; help2man, top Makefile).
SUMMARY.shapesim-smooth := align shapelet models into the morphology model shapesim-sample draws from
