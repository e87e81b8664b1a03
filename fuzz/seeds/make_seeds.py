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

# dpv1_pdu: one DP-V1 PDU (request or response). The record handler's behaviour is chosen by the
# slot: 0 = a store of records 0..7, 1 = error code = index, 2 = reads fill the room, 3 = empty
# reads, else invalid slot.
INITIATE_TYPE0 = [0x57, 0, 0, 0, 0x01, 0x2C, 0x01, 0x00, 0, 0, 0x3A, 0x00, 0, 2, 0, 2, 0x11, 0x22, 0x33, 0x44]
INITIATE_TYPED = [0x57, 0, 0, 0, 0, 100, 1, 0, 0, 0, 0, 0, 1, 10, 0, 2, 1, 2, 10, 11, 12, 13, 14, 15, 0xAA, 0xBB, 0, 0]
VACON_WRITE_918 = [0x5F, 0x00, 0x2F, 0x0A, 0x01, 0x01, 0x01, 0x01, 0x10, 0x01, 0x03, 0x96, 0x00, 0x00]
for name, p in {
    "read_47": [0x5E, 0x00, 0x2F, 0xF0],
    "read_store": [0x5E, 0x00, 0x03, 0x40],
    "read_fill": [0x5E, 0x02, 0x05, 0x10],
    "read_error_slot1": [0x5E, 0x01, 0xB5, 0x10],
    "read_len0": [0x5E, 0x00, 0x2F, 0x00],
    "write_vacon_918": VACON_WRITE_918,
    "write_store": [0x5F, 0x00, 0x01, 0x05, 1, 2, 3, 4, 5],
    "data_transport": [0x51, 0x00, 0x02, 0x03, 7, 8, 9],
    "data_transport_fill": [0x51, 0x02, 0x00, 0x01, 0xAA],
    "alarm_ack": [0x5C, 0x01, 0x01, 0x2D],
    "initiate_type0": INITIATE_TYPE0,
    "initiate_typed": INITIATE_TYPED,
    "abort": [0x58, 0x01, 0x13, 0x00],
    "abort_short": [0x58, 0x01, 0x13],
    "idle": [0x48, 0x00],
    "rm_response": [0x56, 0x30, 0x00, 0x64],
    "error_response": [0xDE, 0x80, 0xB5, 0x00],
    "initiate_response": [0x57, 236, 1, 0, 0, 0, 0x3A, 0x00, 0, 2, 0, 2, 0x33, 0x44, 0x11, 0x22],
    "read_response": [0x5E, 0x00, 0x2F, 0x08, 0x01, 0x01, 0x01, 0x01, 0x42, 0x01, 0x00, 0x03],
}.items():
    write("dpv1_pdu", name, p)

# profidrive: the DS_Write data of record 47 (a parameter request) or record 48 (2 / 4 bytes),
# against the fake table of fuzz_targets/common/fake_drive.rs (PNU 1 U16 0..1000, 2 read-only,
# 3 U16[10], 4 U32[4], 5 string, 6 Byte[200], 7 float, 8 table bug, 9 U16[234], 10 I16).
for name, p in {
    "vacon_read_918": [0x01, 0x01, 0x01, 0x01, 0x10, 0x01, 0x03, 0x96, 0x00, 0x00],
    "change_p1": [0x07, 0x02, 0x01, 0x01, 0x10, 0x01, 0x00, 0x01, 0x00, 0x00, 0x42, 0x01, 0x03, 0xE8],
    "change_p1_limit": [0x08, 0x02, 0x01, 0x01, 0x10, 0x01, 0x00, 0x01, 0x00, 0x00, 0x42, 0x01, 0x17, 0x70],
    "read_array_p3": [0x06, 0x01, 0x01, 0x01, 0x10, 0x03, 0x00, 0x03, 0x00, 0x02],
    "change_array_p3": [0x05, 0x02, 0x01, 0x01, 0x10, 0x03, 0x00, 0x03, 0x00, 0x02, 0x42, 0x03, 0x00, 0x64, 0xC3, 0x50, 0xC3, 0x51],
    "description_p1": [0x02, 0x01, 0x01, 0x01, 0x20, 0x01, 0x00, 0x01, 0x00, 0x00],
    "text_p1": [0x03, 0x01, 0x00, 0x01, 0x30, 0x01, 0x00, 0x01, 0x00, 0x02],
    "read_many": [0x09, 0x01, 0x01, 0x06,
                  0x10, 0x01, 0x00, 0x01, 0x00, 0x00,
                  0x10, 0x00, 0x00, 0x02, 0x00, 0x00,
                  0x10, 0x10, 0x00, 0x05, 0x00, 0x00,
                  0x10, 0x01, 0x00, 0x07, 0x00, 0x00,
                  0x10, 0x01, 0x00, 0x08, 0x00, 0x00,
                  0x10, 0xEA, 0x00, 0x09, 0x00, 0x00],
    "change_odd_bytes_p6": [0x0A, 0x02, 0x01, 0x02, 0x10, 0x03, 0x00, 0x06, 0x00, 0x05, 0x10, 0x01, 0x00, 0x07, 0x00, 0x00,
                            0x41, 0x03, 1, 2, 3, 0x00, 0x08, 0x01, 0x42, 0x48, 0x00, 0x00],
    "change_i16_p10": [0x0B, 0x02, 0x00, 0x01, 0x10, 0x01, 0x00, 0x0A, 0x00, 0x00, 0x03, 0x01, 0xFF, 0x38],
    "bad_axis": [0x0C, 0x01, 0x05, 0x01, 0x10, 0x01, 0x00, 0x01, 0x00, 0x00],
    "bad_reference": [0x00, 0x01, 0x01, 0x01, 0x10, 0x01, 0x00, 0x01, 0x00, 0x00],
    "bad_format": [0x0D, 0x02, 0x01, 0x01, 0x10, 0x01, 0x00, 0x01, 0x00, 0x00, 0x0C, 0x01, 0, 0, 0, 0, 0, 0],
    "weg_select_p1": [0x00, 0x01],
    "weg_write_p1": [0x00, 0x01, 0x01, 0x2C],
    "weg_write_read_only": [0x00, 0x02, 0x00, 0x01],
}.items():
    write("profidrive", name, p)

# node_dpv1: byte 0 picks the module of the bring-up; then operations (see node_dpv1.rs):
# 0/1 C1 request, 2 C1 poll, 3 SAP 51 from others, 4 RM Initiate, 5 whole C2 connect,
# 6 C2 request, 7 C2 poll, 8 SDN, 9 retry, 10 time, 11 process_acyclic, 12 DP cyclic,
# 13 re-parameterise, 14 free-form request, 15 framer toggle / raw bytes.
# record_pdu: 0x00 = Read record 47 (240), 0x40 n = Read record 48 (n), 0x04 = Write record 47
# with a param_request, 0x48 b = Write record 48 (b & 1: 4 bytes), 0x0B Idle, 0x0C Abort.
PR_READ_918 = [0x00, 0xA0, 0x00, 0x00, 0x01]
PR_CHANGE_P1 = [0x02, 0x00, 0x00, 0x00, 0x00, 0x03, 0xE8, 0x07]
C1_READ_918 = [0, 0x04] + PR_READ_918 + [2, 11, 2] + [0, 0x00, 11, 2]
C1_CHANGE = [1, 0x04] + PR_CHANGE_P1 + [11, 2, 9] + [0, 0x00, 2, 11, 2]
C1_WEG = [0, 0x48, 0x01, 0x00, 0x01, 0x01, 0x2C, 11, 2] + [0, 0x48, 0x00, 0x00, 0x01, 11, 2] + [0, 0x40, 0xF0, 11, 2]
write("node_dpv1", "c1_read_change_weg", [0x00] + C1_READ_918 + C1_CHANGE + C1_WEG + [12, 0x00, 1, 2, 3, 4])
write("node_dpv1", "c1_bytewise_retry", [0x00, 15, 0x00] + C1_READ_918 + [9, 9] + C1_CHANGE + [15, 0x00, 9])
write("node_dpv1", "c1_closed_by_prm", [0x00] + [0, 0x04] + PR_READ_918 + [13, 0x04, 0x00] + [11, 2]
      + [0, 0x00, 2] + [13, 0x00, 0x00] + [0, 0x00, 11, 2] + [3, 0x00] + PR_READ_918 + [10, 0xFF, 16, 2])
C2_READ = [6, 0x00, 0x01, 0x04] + PR_READ_918 + [7, 0x00, 11, 7, 0x00] + [6, 0x00, 0x01, 0x00, 11, 7, 0x00]
write("node_dpv1", "c2_two_masters", [0x00] + [5, 0x00] + C2_READ + [5, 0x01] + [6, 0x01, 0x01, 0x0B, 7, 0x01]
      + [5, 0x02] + [6, 0x00, 0x01, 0x0C, 0x00, 0x20, 7, 0x00] + [5, 0x02, 7, 0x02] + [6, 0x02, 0x02, 0x04] + PR_CHANGE_P1
      + [11, 7, 0x02])
write("node_dpv1", "c2_timeout_sdn_abort", [0x00] + [5, 0x00] + [10, 0xFF, 14] + [7, 0x00, 7, 0x00] + [5, 0x00]
      + [8, 0x00, 0x03, 0x00] + [7, 0x00] + [5, 0x81, 0x01, 7, 0x01] + [10, 0x40, 12] + [7, 0x01])
write("node_dpv1", "c2_rm_bad_initiate", [0x00] + [4, 0x00, 0x00] + [4, 0x01, 0x40, 0x07] + [6, 0x01, 0x00, 0x00]
      + [7, 0x01] + [4, 0x00, 0x04, 0x01, 0x02] + [6, 0x00, 0x00, 0x00, 0x04, 0x01, 0x02] + [7, 0x00] + [11, 7, 0x00]
      + [14, 10, 5, 0x0D, 0x02, 0x00, 0x04] + PR_READ_918)
# An Initiate.req longer than a PDU may be (parses, cannot be re-emitted; FDL never delivers it).
write("dpv1_pdu", "initiate_longer_than_pdu", [0x57, 0, 0, 0, 0, 100, 1, 0, 0, 0, 0, 0, 1, 240, 0, 2] + [7] * 240 + [0, 0])
# The two known MSAC_C1 bugs (see KNOWN_BUG_* in node_dpv1.rs): a broadcast SDN Alarm_Ack on
# SAP 51 from the locking master replaces the pending DS_Read; a DS_Write sent before a new
# Set_Prm + Chk_Cfg is still executed and answered afterwards.
write("node_dpv1", "known_bug_c1_broadcast_sdn", [0x00, 0, 0x00, 14, 2, 0, 0x06, 0x85, 0x01, 0x0A, 0x01, 0x02, 11, 2])
write("node_dpv1", "known_bug_c1_stale_request", [0x00, 0, 0x04] + PR_READ_918 + [13, 0x00, 0x00, 11, 2])

# pkw: byte 0 = dialect (0 VACON, 1 INVT, 2 PROFIdrive 2.0) + 4 x slowness (0: the drive answers
# at once; 1..3: behind the mailbox, answering after every that many services);
# then 9-byte steps: op (1 request, 2 service, 4 repeat, 8 reset, 16 the drive answers now) + the
# 8 request bytes.
def pkw_step(op, *words):
    return [op] + [b for w in words for b in w.to_bytes(2, "big")]


write("pkw", "vacon_6_6_3", [0x00] + pkw_step(3, 0x1066, 0, 0, 0) + pkw_step(6, 0, 0, 0, 0)
      + pkw_step(3, 0x207D, 0, 0, 2) + pkw_step(3, 0x207D, 0, 0, 2) + pkw_step(3, 0x3066, 0, 0, 0))
write("pkw", "invt_example_slow", [0x01 | 2 << 2] + pkw_step(1, 1, 0x0010, 0, 0) + pkw_step(2, 0, 0, 0, 0) * 3
      + pkw_step(3, 4, 1, 0, 300) + pkw_step(2, 0, 0, 0, 0) * 3 + pkw_step(3, 2, 1, 0, 1) + pkw_step(11, 0, 0, 0, 0))
write("pkw", "profidrive2_ak", [0x02 | 1 << 2] + pkw_step(3, 0x6003, 0x0200, 0, 0) + pkw_step(2, 0, 0, 0, 0)
      + pkw_step(3, 0x7003, 0x0100, 0, 77) + pkw_step(2, 0, 0, 0, 0) + pkw_step(3, 0x3004, 0, 0x0A5C, 0xDD50)
      + pkw_step(2, 0, 0, 0, 0) + pkw_step(3, 0x9003, 0, 0, 0) + pkw_step(3, 0x4001, 0x0100, 0, 0)
      + pkw_step(3, 0x2002, 0, 0, 1) + pkw_step(3, 0xF001, 0, 0, 0))


# dpm_spi: control byte (bit 0: 0 = card transaction, 1 = host reply decode; bit 1: fix the
# CRC), then the bytes. Request frame: CMD TAG ADDR(2) LEN(2) DATA CRC16/CCITT-FALSE (big-endian).
def spi_frame(cmd, tag, addr, ln, data=b""):
    import binascii
    f = bytes([cmd, tag]) + addr.to_bytes(2, "big") + ln.to_bytes(2, "big") + bytes(data)
    return f + binascii.crc_hqx(f, 0xFFFF).to_bytes(2, "big")


write("dpm_spi", "read_status", b"\x00" + spi_frame(0xA1, 1, 0x10, 32))
write("dpm_spi", "read_all_padded", b"\x00" + spi_frame(0xA1, 2, 0, 624) + bytes(8))
write("dpm_spi", "write_inputs", b"\x00" + spi_frame(0xB2, 3, 0x78, 4, [0x04, 0x7F, 0x12, 0x34]))
write("dpm_spi", "write_card_block", b"\x00" + spi_frame(0xB2, 4, 0xC0, 2, [1, 2]))
write("dpm_spi", "status", b"\x00" + spi_frame(0xC4, 5, 0, 0))
write("dpm_spi", "fix_crc_write", b"\x02" + spi_frame(0xB2, 6, 0x120, 3, [5, 0, 0]))
write("dpm_spi", "reply", b"\x01" + bytes([0x80, 1, 0xA1, 0, 0, 0x10, 0, 2, 0xAA, 0xBB, 0, 0]))

# phy_line: control byte c: c >> 6 == 0 a segment of (c & 0x3F) + 1 bytes, 1 the same with a
# character error ((c & 0x3F) bytes), 2 T_SYN (c & 1 == 0) or receiver reset, 3 (c & 3) + 1
# well-formed telegrams (kind byte % 8: 0 SC, 1 token, else a request; b4 = to station 5,
# b5 = with SAPs; then DA?, SA, FC, DSAP?, PDU length % 40, PDU), with c & 4 then
# (c >> 3) & 7 garbage bytes.
TSYN, RESET = 0x80, 0x81


def segment(b):
    return [len(b) - 1] + list(b)


def well_formed(*reqs):
    return [0xC0 | (len(reqs) - 1)] + [x for r in reqs for x in r]


REQ_SET_PRM = [0x32, 2, 0x6D, 61, len(SET_PRM)] + SET_PRM  # to us, with SAPs
REQ_DX = [0x12, 2, 0x7D, 4, 0x04, 0x7E, 0x00, 0x00]  # to us, Data_Exchange
write("phy_line", "tsyn_then_frames", [TSYN] + segment(FRAMES["set_prm"]) + segment(FRAMES["chk_cfg"] + FRAMES["token_sc"])
      + segment(FRAMES["data_exchange_sd3"]))
write("phy_line", "unsynced_corrupt_truncated", segment(FRAMES["fdl_status"]) + [TSYN, 0x40 | 3, 1, 2, 3]
      + segment(FRAMES["set_prm"]) + [TSYN] + segment(FRAMES["diag_response"][:7]) + [TSYN]
      + segment(FRAMES["diag_response"]))
write("phy_line", "well_formed_and_garbage", [TSYN] + well_formed(REQ_SET_PRM, [0], [1, 9], REQ_DX)
      + [0xC4 | (3 << 3) | 1] + REQ_DX + [0x10, 0xFF] + [0xAA, 0x68, 0x05] + [TSYN, RESET] + well_formed(REQ_DX)
      + [TSYN] + well_formed(REQ_DX))

# dpm_host_blocks: byte 0 the module of the bring-up; then operations c % 8: 0 raw bytes into
# a host-written block (block index % 5: INPUTS, DRIVE, CONFIG, MBX_RSP, DRIVE_STATE; offset,
# length, bytes), 1 a whole host block of input bytes with equal counters (index, bytes,
# counter), 2 a CONFIG with a new counter (address, profile % 3, reaction % 6, operate % 5),
# 3 raw bytes into a card-written block (index % 7), 4 Data_Exchange, 5 time (b × 4 ms),
# else one step.
DX_ST1 = [4, 0x04, 0x7E, 0x00, 0x00]
write("dpm_host_blocks", "torn_drive_and_config", [0x00] + [6] * 3 + DX_ST1 + [0, 1, 0, 1, 0x12] + [6]
      + [0, 2, 46, 2, 0x77, 0x77] + DX_ST1 + [6])
write("dpm_host_blocks", "refused_config_and_ext_diag", [0x00] + [2, 200, 0, 0, 0] + [2, 3, 2, 0, 0]
      + [1, 1] + [0, 9, 1, 0, 0, 0, 0, 40] + [0xEE] * 32 + [0] * 2 + [0, 9] + DX_ST1 + [6])
write("dpm_host_blocks", "drive_state_inputs_then_loss", [0x01] + [1, 4] + [0x55] * 40 + [0, 7] + [1, 0] + [0, 7, 1, 4]
      + [0x04, 0x37, 0x12, 0x34] + [0] * 60 + [0, 8] + DX_ST1 + [5, 100] + DX_ST1 + [5, 250] + DX_ST1)
write("dpm_host_blocks", "card_blocks_scribbled", [0x00] + DX_ST1 + [3, 0, 0, 4, 0, 0, 0, 0] + [6] + [3, 5, 0, 32]
      + [0xFF] * 32 + [6] + [3, 6, 0, 8] + [1] * 8 + DX_ST1 + [5, 50])

# fast_path: byte 0 bit 0 the schedule (0 sync, 1 lag); then pbcard::fast::check operations
# (op, master selector < 170 = master 2, then the op's bytes): 18 the start-up pair (Set_Prm +
# Chk_Cfg of module 0), 2 Data_Exchange (0 = the configured length, then the bytes), 3
# Slave_Diag, 6 Global_Control (0 broadcast, command, group), 7 the last request again (a
# retry), 8 other stations' traffic, 10 FDL_Status, 12 time, 15 DP-V1.
FP_UP = [18, 0, 0]
FP_DX = [2, 0, 0, 1, 2, 3, 4]
write("fast_path", "bring_up_dx_retry", [0] + FP_UP + FP_DX + [7, 0] + [3, 0] + FP_DX + [10, 0])
write("fast_path", "window_diag", [1] + FP_UP + [3, 0] + [3, 0] + [8, 0, 9, 9, 9, 9] + [10, 0] + FP_DX)
write("fast_path", "gc_sync_not_supported", [0] + FP_UP + [6, 0, 1, 0x20, 0] + FP_DX + [3, 0] + FP_DX + [3, 0])
write("fast_path", "dpv1_and_clear", [0] + FP_UP + [15, 0, 0, 4, 0x5E, 0, 1, 4] + [6, 0, 0, 0x02, 0] + FP_DX
      + [2, 0, 2] + [12, 0, 60] + FP_DX)
