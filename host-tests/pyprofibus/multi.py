"""pyprofibus (PyPI) with several slaves on one line: one soft slave process serving them all.

usage: multi.py DEVICE SECONDS ADDRESS:MODULE_NAME:SIZE:SETPOINT ...

Brings every slave up with its module, runs 0x047E (ready) then 0x047F with the slave's own
setpoint, and passes (exit code 0) when every slave reached data exchange, shows "operation
enabled" (ZSW1 bit 2) and its actual speed reached its own setpoint — the drives are independent.
"""
import os
import sys
import time

import pyprofibus

HERE = os.path.dirname(os.path.abspath(__file__))
GSD = os.path.join(HERE, "..", "..", "gsd", "ODCP0F11.gsd")


def main():
    dev, seconds = sys.argv[1], float(sys.argv[2])
    slaves = []
    for spec in sys.argv[3:]:
        addr, module, size, setpoint = spec.split(":")
        slaves.append({"addr": int(addr), "module": module, "size": int(size), "setpoint": int(setpoint, 0)})
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
"""
    for i, s in enumerate(slaves):
        conf_text += f"""
[SLAVE_{i}]
name = drive{s['addr']}
addr = {s['addr']}
gsd = {GSD}
sync_mode = 0
freeze_mode = 0
group_mask = 1
watchdog_ms = 5000
module_0 = {s['module']}
output_size = {s['size']}
input_size = {s['size']}
"""
    path = os.path.join(os.environ.get("TMPDIR", "/tmp"), f"pbcard-pyprofibus-multi-{os.getpid()}.conf")
    with open(path, "w") as f:
        f.write(conf_text)
    conf = pyprofibus.PbConf.fromFile(path)
    master = conf.makeDPM()
    for s, sc in zip(slaves, conf.slaveConfs):
        s["desc"] = sc.makeDpSlaveDesc()
        s.update(first=None, enabled=False, best=0, exchanges=0)
        master.addSlave(s["desc"])
    master.initialize()
    t0 = time.time()
    try:
        while time.time() - t0 < seconds:
            for s in slaves:
                out = bytearray(s["size"])
                running = s["first"] is not None and time.time() - s["first"] > 1.0
                out[0:2] = (0x047F if running else 0x047E).to_bytes(2, "big")
                out[2:4] = s["setpoint"].to_bytes(2, "big")
                s["desc"].setMasterOutData(bytes(out))
            master.run()
            for s in slaves:
                data = s["desc"].getMasterInData()
                if data is None:
                    continue
                s["exchanges"] += 1
                if s["first"] is None:
                    s["first"] = time.time()
                    print(f"pyprofibus: data exchange with #{s['addr']} ({s['module']}) after {s['first'] - t0:.2f} s", flush=True)
                zsw = int.from_bytes(data[0:2], "big")
                nist = int.from_bytes(data[2:4], "big", signed=True)
                if time.time() - s["first"] > 1.0:
                    s["enabled"] |= bool(zsw & 0x0004)
                    s["best"] = max(s["best"], nist)
            if all(s["enabled"] and s["best"] >= s["setpoint"] for s in slaves):
                break
    finally:
        master.destroy()
    ok = True
    for s in slaves:
        good = s["first"] is not None and s["enabled"] and s["best"] >= s["setpoint"]
        ok &= good
        print(f"pyprofibus: #{s['addr']}: {s['exchanges']} Data_Exchange, operation enabled: {s['enabled']}, "
              f"actual speed {s['best']:#06x} of {s['setpoint']:#06x}: {'ok' if good else 'FAILED'}", flush=True)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
