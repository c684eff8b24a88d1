# shapesim-lens: one thin main.cpp linked against the library (rule in the top Makefile).
PROGRAMS += shapesim-lens
# Its man page's one line (NAME section; help2man, top Makefile).
SUMMARY.shapesim-lens := give every galaxy the lensing it sees: shear fields, NFW halos, constant shear
