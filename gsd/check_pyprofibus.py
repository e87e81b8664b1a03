#!/usr/bin/env python3
"""Check that pyprofibus (1.13, `pip install pyprofibus`) reads the card's GSD the way a
pyprofibus DP master would use it, and print what it sees.

Usage: python3 gsd/check_pyprofibus.py [path/to/ODCP0F11.gsd]
Exit status 0 = pyprofibus parsed the file and every check passed, 1 = a check failed.

pyprofibus' GSD reader is line/regex based and much more lenient than gsd-parser in some
respects (it silently ignores unknown lines) and stricter in others (case-sensitive keywords,
a restricted character set in strings, `;` ends a line even inside some strings). The Rust test
host-tests/tests/gsd.rs checks the values against src/card.rs; this script only checks that
pyprofibus extracts the same modules, ident, MaxTsdr values and user parameter bytes.
"""

import os
import sys

from pyprofibus.gsd.interp import GsdInterp

RATES = (9600, 19200, 45450, 93750, 187500, 500000, 1500000, 3000000, 6000000, 12000000)


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    path = sys.argv[1] if len(sys.argv) > 1 else os.path.join(here, "ODCP0F11.gsd")
    gsd = GsdInterp.fromFile(path)
    errors = []

    def check(cond, msg):
        if not cond:
            errors.append(msg)

    print(str(gsd), end="")
    ident = gsd.getIdentNumber()
    check(ident is not None, "no Ident_Number")
    check(gsd.getField("Vendor_Name"), "no Vendor_Name")
    check(gsd.getField("Model_Name"), "no Model_Name")
    check(gsd.isModular(), "Modular_Station is not 1")
    check(gsd.isDPV1(), "DPV1_Slave is not 1 (card::DPV1_SLAVE)")
    for rate in RATES:
        tsdr = gsd.getMaxTSDR(rate)
        check(tsdr is not None, "no MaxTsdr for %d bit/s" % rate)
        check(gsd.getField(supp_name(rate)), "%s is not 1" % supp_name(rate))
    print("MaxTsdr:           " + ", ".join("%d: %s" % (r, gsd.getMaxTSDR(r)) for r in RATES))

    modules = gsd.getField("Module", [])
    check(len(modules) > 0, "no modules")
    for mod in modules:
        # Select the module by name as a pyprofibus .conf file would, and build Chk_Cfg.
        gsd.clearConfiguredModules()
        gsd.setConfiguredModule(mod.name)
        chk_cfg = bytearray()
        for elem in gsd.getCfgDataElements():
            chk_cfg += elem.getDU()
        print("Module:            %-24s Chk_Cfg %s" % ('"%s"' % mod.name, chk_cfg.hex(" ")))
        check(bytes(chk_cfg) == bytes(mod.configBytes),
              "module %r: Chk_Cfg %s != GSD cfg %s" % (mod.name, chk_cfg.hex(), mod.configBytes.hex()))

    prm = gsd.getUserPrmData()
    max_len = gsd.getField("Max_User_Prm_Data_Len")
    print("User_Prm_Data:     %s (Max_User_Prm_Data_Len %s)" % (prm.hex(" "), max_len))
    check(max_len is not None and len(prm) == max_len,
          "User_Prm_Data from Ext_User_Prm_Data_Const is %d bytes, Max_User_Prm_Data_Len %s"
          % (len(prm), max_len))
    for ref in gsd.getField("Ext_User_Prm_Data_Ref", []):
        defined = [d.refNr for d in gsd.getField("ExtUserPrmData", [])]
        check(ref.refNr in defined, "Ext_User_Prm_Data_Ref(%d) = %d is not defined" % (ref.offset, ref.refNr))

    if errors:
        for e in errors:
            print("ERROR: " + e, file=sys.stderr)
        return 1
    print("pyprofibus: OK")
    return 0


def supp_name(rate):
    return {
        9600: "9.6_supp", 19200: "19.2_supp", 45450: "45.45_supp", 93750: "93.75_supp",
        187500: "187.5_supp", 500000: "500_supp", 1500000: "1.5M_supp", 3000000: "3M_supp",
        6000000: "6M_supp", 12000000: "12M_supp",
    }[rate]


if __name__ == "__main__":
    sys.exit(main())
