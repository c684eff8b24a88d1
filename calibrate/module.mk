# shapesim-calibrate: one thin main.cpp linked against the library (rule in the top Makefile).
PROGRAMS += shapesim-calibrate
# Its man page's one line (NAME section; help2man, top Makefile).
SUMMARY.shapesim-calibrate := shear calibration: any shape catalogue against the truth, m and c
