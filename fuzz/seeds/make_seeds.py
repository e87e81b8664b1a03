#!/usr/bin/env python3
"""Writes the seed inputs of the fuzz targets (fuzz/seeds/<target>/*.bin). Re-run after changing
a target's input encoding: `python3 fuzz/seeds/make_seeds.py`."""
import os

HERE = os.path.dirname(os.path.abspath(__file__))
IDENT = [0x0F, 0x11]
ST1 = [0xC3, 0xC1, 0xC1, 0xFD, 0x00, 0x01]
USER_DEFAULTS = [0, 0, 0, 0, 0]


def fcs(b):
    return sum(b) & 0xFF


def frame(da, sa, fc, dsap=None, ssap=None, pdu=()):
    """The frame telegram::emit builds (SD1 / SD3 / SD2 by DU length)."""
    body = [da | (0x80 if dsap is not None else 0), sa | (0x80 if ssap is not None else 0), fc]
    if dsap is not None:
        body.append(dsap)
    if ssap is not None:
        body.append(ssap)
    body += list(pdu)
    du = len(body) - 3
    if du == 0:
        return bytes([0x10] + body + [fcs(body), 0x16])
    if du == 8:
        return bytes([0xA2] + body + [fcs(body), 0x16])
    le = len(body)
    return bytes([0x68, le, le, 0x68] + body + [fcs(body), 0x16])


def req(da, sa, func, fcb, fcv, dsap=None, pdu=()):
    fc = 0x40 | (fcb << 5) | (fcv << 4) | func
    return frame(da, sa, fc, dsap, 62 if dsap is not None else None, pdu)


SET_PRM = [0x88, 10, 10, 11] + IDENT + [0x01] + USER_DEFAULTS
FRAMES = {
    "fdl_status": bytes([0x10, 0x08, 0x02, 0x49, 0x53, 0x16]),
    "set_prm": req(8, 2, 0xD, 1, 1, 61, SET_PRM),
    "chk_cfg": req(8, 2, 0xD, 0, 1, 62, ST1),
    "data_exchange_sd3": req(8, 2, 0xD, 1, 1, None, [1, 2, 3, 4, 5, 6, 7, 8]),
    "data_exchange_sd2": req(8, 2, 0xD, 1, 1, None, [1, 2, 3, 4]),
    "global_control": req(127, 2, 0x6, 0, 0, 58, [0x28, 0x00]),
    "diag_response": frame(2, 8, 0x08, 62, 60, [0x08, 0x0C, 0x00, 0x02, 0x0F, 0x11, 0x02]),
    "token_sc": bytes([0xDC, 0x03, 0x02, 0xE5]),
}


def write(target, name, data):
    d = os.path.join(HERE, target)
    os.makedirs(d, exist_ok=True)
    with open(os.path.join(d, name + ".bin"), "wb") as f:
        f.write(bytes(data))


# telegram: single frames.
for name, f in FRAMES.items():
    write("telegram", name, f)


# framer: control byte c < 0xC0 pushes the next c + 1 bytes; c >= 0xC0 is an idle gap of
# c & 0x3F bit times (0xE1 = 33 = T_SYN).
def chunk(b):
    return [len(b) - 1] + list(b)


write("framer", "frames_with_gaps", chunk(FRAMES["fdl_status"]) + [0xE1] + chunk(FRAMES["set_prm"]) + [0xE1]
      + chunk(FRAMES["chk_cfg"] + FRAMES["token_sc"]) + [0xE1] + chunk(FRAMES["data_exchange_sd3"]))
write("framer", "garbage_then_frame", chunk([0x00, 0xFF, 0x68, 0x99, 0x12, 0x10, 0x33]) + chunk(FRAMES["data_exchange_sd2"])
      + [0xC5] + chunk(FRAMES["diag_response"][:7]) + [0xE1] + chunk(FRAMES["diag_response"]))
write("framer", "back_to_back", chunk(FRAMES["set_prm"] + FRAMES["chk_cfg"] + FRAMES["global_control"]))

# dp_params: the PDUs the parsers see.
write("dp_params", "set_prm", SET_PRM)
write("dp_params", "set_prm_sync_freeze_1ms", [0xB8, 1, 99, 11] + IDENT + [0x22, 0x04, 0, 0, 1, 2])
write("dp_params", "chk_cfg_st1", ST1)
write("dp_params", "chk_cfg_ppo2", [0xF3, 0xF5])
write("dp_params", "ext_diag", [0x04, 0x01, 0x00, 0x00, 0x81, 0x41, 0x25])
write("dp_params", "set_slave_add", [20] + IDENT + [0])
write("dp_params", "global_control", [0x28, 0x00])

# slave: byte 0 picks the Set_Prm of the bring-up (value % 6: 0 = 0x88, 1 = 0xB8, 2 = 0x80 ...;
# b7 = 1 ms WD base, e.g. 0x84 = 0x88 with 1 ms), byte 1 the module (0 = standard telegram 1,
# 5 = PPO 5); then operations (see slave.rs):
# 3 DX (2 = right length), 5 Set_Prm, 6 Chk_Cfg, 7 Global_Control, 8 Set_Slave_Add,
# 9 read (diag/get_cfg/rd_inp/rd_outp), 10 retry, 11 time, 12 inputs, 13 ext diag,
# 14 stat diag, 15 raw frame (+0x10: FCS repaired), 0..2 free-form request.
DX = lambda *o: [3, 2] + list(o)
write("slave", "dx_retry_inputs", [0x00, 0x00] + DX(1, 2, 3, 4) + [10] + [12, 4, 9, 9, 9, 9] + [10]
      + DX(5, 5, 5, 5) + [9, 0, 0] + [10] + [11, 0xFF, 12] + DX(6, 6, 6, 6))
write("slave", "sync_freeze", [0x01, 0x00] + [7, 0, 0, 0x28, 0x00] + DX(1, 0, 0, 0) + [12, 4, 1, 1, 1, 1]
      + [7, 0, 0, 0x20, 0x00] + DX(2, 0, 0, 0) + [10] + [7, 0, 0, 0x04, 0x00] + DX(3, 0, 0, 0) + [9, 0, 2]
      + [7, 0, 0, 0x02, 0x01])
write("slave", "unlock_set_slave_add", [0x00, 0x00] + [5, 0, 0x40, 10, 10, 11, 1, 0] + [8, 4, 20, 1, 1] + [9, 4, 0]
      + [0, 4, 3, 0x0D, 0x08, 0] + [5, 4, 0x88, 2, 2, 0, 1, 0] + [6, 4, 0] + [3 | 0x80, 2, 1, 2, 3, 4, 4])
write("slave", "watchdog_1ms", [0x84, 0x00] + DX(1, 1, 1, 1) + [11, 200, 10] + DX(2, 2, 2, 2) + [9, 0, 0]
      + [5, 0, 0x88, 10, 10, 11, 1, 0] + [6, 0, 0] + DX(3, 3, 3, 3))
fdl_status = list(FRAMES["fdl_status"])
write("slave", "ext_diag_raw_ppo5", [0x00, 0x05] + [13, 0x04, 0, 2, 2, 5] + [3, 2] + list(range(28)) + [9, 0, 0]
      + [14 | 0x10] + [0x1F, len(fdl_status)] + fdl_status + [15, 6, 0x10, 8, 2, 0x49, 0x00, 0x16]
      + [13, 0x0B] + list(range(5)) + [9, 0, 1])
