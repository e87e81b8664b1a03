"""pyprofibus (PyPI, a DP-V0 master nobody here wrote) against our slave on a pseudo-terminal.

usage: master.py DEVICE ADDRESS MODULE_NAME SIZE SECONDS

Brings the slave up with the GSD's module MODULE_NAME (SIZE bytes each way) at ADDRESS, runs the
PROFIdrive control word 0x047E (ready) and then 0x047F with a 50 % setpoint, and checks what the
slave answers: data exchange reached, ZSW1 shows "operation enabled" (bit 2) and the actual speed
rises to the setpoint. Exit code 0 = pass. PPO types with a PKW carry STW1/HSW in words 4/5.
"""
import os
import sys
import time

import pyprofibus

HERE = os.path.dirname(os.path.abspath(__file__))
GSD = os.path.join(HERE, "..", "..", "gsd", "ODCP0F11.gsd")


def main():
    dev, addr, module, size, seconds = sys.argv[1], int(sys.argv[2]), sys.argv[3], int(sys.argv[4]), float(sys.argv[5])
    conf_text = f"""
[PROFIBUS]
debug = 0
[PHY]
type = serial
dev = {dev}
baud = 19200
[DP]
master_class = 1
master_addr = 2
[SLAVE_0]
name = drive
addr = {addr}
gsd = {GSD}
sync_mode = 0
freeze_mode = 0
group_mask = 1
watchdog_ms = 5000
module_0 = {module}
output_size = {size}
input_size = {size}
"""
    path = os.path.join(os.environ.get("TMPDIR", "/tmp"), f"pbcard-pyprofibus-{os.getpid()}.conf")
    with open(path, "w") as f:
        f.write(conf_text)
    conf = pyprofibus.PbConf.fromFile(path)
    master = conf.makeDPM()
    desc = conf.slaveConfs[0].makeDpSlaveDesc()
    master.addSlave(desc)
    master.initialize()
    pkw = 8 if module.startswith("PPO") and "PKW" in module else 0
    t0 = time.time()
    first = None
    exchanges = 0
    best_speed = 0
    enabled = False
    run_from = None
    try:
        while time.time() - t0 < seconds:
            out = bytearray(size)
            running = first is not None and time.time() - first > 1.0
            if running and run_from is None:
                run_from = exchanges
            out[pkw:pkw + 2] = (0x047F if running else 0x047E).to_bytes(2, "big")
            out[pkw + 2:pkw + 4] = (0x2000).to_bytes(2, "big")
            desc.setMasterOutData(bytes(out))
            master.run()
            data = desc.getMasterInData()
            if data is None:
                continue
            exchanges += 1
            if first is None:
                first = time.time()
                print(f"pyprofibus: data exchange with #{addr} ({module}) after {first - t0:.2f} s", flush=True)
            zsw = int.from_bytes(data[pkw:pkw + 2], "big")
            nist = int.from_bytes(data[pkw + 2:pkw + 4], "big", signed=True)
            if running:
                enabled |= bool(zsw & 0x0004)
                best_speed = max(best_speed, nist)
            if best_speed >= 0x2000 and enabled:
                break
    finally:
        master.destroy()
    print(f"pyprofibus: {exchanges} Data_Exchange, ZSW1 operation enabled: {enabled}, "
          f"actual speed reached {best_speed:#06x} of 0x2000", flush=True)
    return 0 if first is not None and enabled and best_speed >= 0x2000 else 1


if __name__ == "__main__":
    sys.exit(main())
