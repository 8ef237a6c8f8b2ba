"""``snapcorr shift``: the mean central-wavelength shift at chief-ray angles (Eq. 22-23)."""

from __future__ import annotations

import numpy as np

from .._names import MEAN_SHIFT_METHOD_NAMES
from ._options import _f_number, _lens, _positive, add_command

#: Its line in ``snapcorr --help``, and the start of its own.
HELP = "mean central-wavelength shift at chief-ray angles (Eq. 22-23)"

#: Its examples (its --help shows them; ``snapcorr --help`` shows all).
EXAMPLES = r"""
      snapcorr shift --f-number 1.4 --cra 0 10 20
                                          mean shift of 700 nm filters behind the bundled lens
      snapcorr shift --lens my_lens.toml --f-number 2.8 --cra 15 --cwl-nm 850 --n-eff 1.9
    """


def add_parser(subparsers):
    p = add_command(subparsers, "shift", HELP, EXAMPLES)
    p.add_argument("--lens", default="edmund_optics_16mm",
                   help="lens profile (.toml) or a bundled lens name (default: %(default)s)")
    p.add_argument("--f-number", type=_f_number, required=True, metavar="F",
                   help="f-number of the lens")
    p.add_argument("--cra", type=float, nargs="+", required=True, metavar="DEG",
                   help="chief-ray angles, degrees (one or more)")
    p.add_argument("--cwl-nm", type=float, default=700.0, metavar="NM",
                   help="the filter's central wavelength at normal incidence, nm (default: "
                   "%(default)s)")
    p.add_argument("--n-eff", type=float, default=1.7,
                   help="the filter's effective refractive index (default: %(default)s)")
    p.add_argument("--method", default="auto", choices=list(MEAN_SHIFT_METHOD_NAMES),
                   help="how to compute the mean shift (default: %(default)s, the cheapest "
                   "within --tolerance-nm)")
    p.add_argument("--tolerance-nm", type=_positive, default=0.001, metavar="NM",
                   help="largest error allowed with --method auto, nm (default: %(default)s)")
    p.set_defaults(func=run)


def run(args):
    from .._validation import check_wavelengths_nm
    from ..optics import mean_shift, select_method

    lens = _lens(args.lens)
    check_wavelengths_nm("--cwl-nm", [args.cwl_nm])
    cra = np.asarray(args.cra, float)
    cutoff = float(lens.cutoff_cra_deg(args.f_number))
    past = np.abs(cra) >= cutoff
    if np.any(past):
        given = float(cra.flat[np.argmax(np.abs(cra))])  # as given, its sign kept
        raise ValueError(f"--cra {given:g} deg is past the full cut-off at {cutoff:.2f} deg "
                         f"(of either sign) for f/{args.f_number:g}: the lens's vignetting "
                         "circles leave no light; give --cra values between "
                         f"-{cutoff:.2f} and {cutoff:.2f}")
    shift = mean_shift(args.cwl_nm, args.n_eff, args.f_number, cra, lens, method=args.method,
                       tolerance_nm=args.tolerance_nm)
    if args.method == "auto":
        used = select_method(args.n_eff, args.f_number, cra, lens, cwl_nm=args.cwl_nm,
                             tolerance_nm=args.tolerance_nm)
    else:
        used = np.full(cra.shape, args.method)
    print(f"# {lens.name}, f/{args.f_number:g}, cwl {args.cwl_nm:g} nm, n_eff {args.n_eff:g}")
    print(f"{'cra_deg':>8} {'shift_nm':>10} {'corrected_nm':>13}  method")
    for c, s, m in zip(cra, np.atleast_1d(shift), np.atleast_1d(used), strict=True):
        print(f"{c:>8.3f} {s:>10.4f} {args.cwl_nm + s:>13.4f}  {m}")
    return 0

