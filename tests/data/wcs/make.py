#!/usr/bin/python3
"""Writes tpv.fits and zpn.fits: 64 x 64 zero images whose headers carry a survey's WCS
(a DECam-like TPV with third-order terms; VISTA VIRCAM's ZPN), and prints astropy's
all_pix2world (origin 1) at test pixels: the reference values of geometry_test.cpp."""
import numpy as np
from astropy.io import fits
from astropy.wcs import WCS

tpv = {
    'CTYPE1': 'RA---TPV', 'CTYPE2': 'DEC--TPV', 'CRPIX1': 1024.5, 'CRPIX2': 2048.5,
    'CRVAL1': 52.6401, 'CRVAL2': -27.9352, 'CUNIT1': 'deg', 'CUNIT2': 'deg',
    'CD1_1': -7.3e-05, 'CD1_2': 1.2e-07, 'CD2_1': -1.1e-07, 'CD2_2': 7.3e-05,
    'PV1_0': 0.00125, 'PV1_1': 1.0107, 'PV1_2': -0.0074, 'PV1_4': 0.0112, 'PV1_5': -0.0065,
    'PV1_6': 0.0041, 'PV1_7': -0.0131, 'PV1_8': 0.0026, 'PV1_9': -0.0114, 'PV1_10': 0.0019,
    'PV2_0': -0.0021, 'PV2_1': 1.0098, 'PV2_2': 0.0068, 'PV2_4': 0.0095, 'PV2_5': -0.0049,
    'PV2_6': 0.0052, 'PV2_7': -0.0118, 'PV2_8': 0.0031, 'PV2_9': -0.0102, 'PV2_10': 0.0024,
    'RADESYS': 'ICRS'}
zpn = {
    'CTYPE1': 'RA---ZPN', 'CTYPE2': 'DEC--ZPN', 'CRPIX1': 6037.5, 'CRPIX2': -1500.5,
    'CRVAL1': 150.1163, 'CRVAL2': 2.2009, 'CUNIT1': 'deg', 'CUNIT2': 'deg',
    'CD1_1': -9.4e-05, 'CD1_2': 2.0e-07, 'CD2_1': 1.5e-07, 'CD2_2': 9.4e-05,
    'PV2_1': 1.0, 'PV2_3': 44.0, 'PV2_5': -10300.0, 'RADESYS': 'ICRS'}
for name, cards in (('tpv', tpv), ('zpn', zpn)):
    h = fits.Header()
    for k, v in cards.items():
        h[k] = v
    fits.PrimaryHDU(np.zeros((64, 64), dtype=np.float32), header=h).writeto(
        name + '.fits', overwrite=True)
    w = WCS(fits.getheader(name + '.fits'))
    for x, y in ((1, 1), (64, 64), (32.25, 17.5), (-3000, 5000), (cards['CRPIX1'], cards['CRPIX2'])):
        ra, dec = w.all_pix2world(x, y, 1)
        print(f'{name} {x!r} {y!r} {float(ra)!r} {float(dec)!r}')
