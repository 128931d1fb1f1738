#!/usr/bin/env python3
"""Fault injection against a running threshing_sim_node (scripts/soak.sh): a 10 kHz command
flood with NaN and too-fast speeds among valid ones, a reset storm, NaN through
dynamic_reconfigure. Prints one line per fault and exits 1 if the node stopped answering."""
import math
import sys
import time

import rospy
from dynamic_reconfigure.msg import Config, DoubleParameter
from dynamic_reconfigure.srv import Reconfigure, ReconfigureRequest
from std_msgs.msg import Float64
from std_srvs.srv import Trigger


def main(flood_s):
    rospy.init_node("soak_faults", anonymous=True)
    ok = True
    pub = rospy.Publisher("/drum_speed_cmd", Float64, queue_size=1000)
    time.sleep(1.0)
    sent = bad = 0
    end = time.time() + flood_s
    values = [80.0, float("nan"), 90.0, float("inf"), 1e4, 85.0]
    while time.time() < end:
        v = values[sent % len(values)]
        bad += 0 if math.isfinite(v) and abs(v) <= 400 else 1
        pub.publish(Float64(v))
        sent += 1
    time.sleep(1.5)  # the node's diagnostics (once per wall second) catch up
    print(f"flood: {sent} commands in {flood_s} s ({sent / flood_s:.0f} Hz), {bad} invalid "
          "(the node counts those it receives; its queue of 100 drops the rest under flood)")
    rospy.wait_for_service("/threshing_sim_node/reset", 10)
    reset = rospy.ServiceProxy("/threshing_sim_node/reset", Trigger)
    answers = {"ok": 0, "refused": 0}
    for _ in range(50):
        r = reset()
        answers["ok" if r.success else "refused"] += 1
    print(f"reset storm: 50 calls, {answers['ok']} reset, {answers['refused']} deferred past "
          f"their limit or refused (start poses overlapping)")
    rospy.wait_for_service("/threshing_sim_node/set_parameters", 10)
    reconf = rospy.ServiceProxy("/threshing_sim_node/set_parameters", Reconfigure)
    req = ReconfigureRequest(Config(doubles=[DoubleParameter("contact_state_rate", float("nan")),
                                             DoubleParameter("tooth_kernel_restitution",
                                                             float("nan"))]))
    r = reconf(req)
    kept = {d.name: d.value for d in r.config.doubles}
    nan_kept = any(math.isnan(v) for v in kept.values())
    print(f"nan reconfigure: server holds contact_state_rate {kept.get('contact_state_rate')}, "
          f"tooth_kernel_restitution {kept.get('tooth_kernel_restitution')}")
    ok &= not nan_kept
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main(float(sys.argv[1]) if len(sys.argv) > 1 else 3.0))
