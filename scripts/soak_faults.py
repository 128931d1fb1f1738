#!/usr/bin/env python3
"""Fault injection against a running threshing_sim_node (scripts/soak.sh), after the command
flood (drum_cmd_flood): a reset storm and NaN through dynamic_reconfigure. Prints one line per
fault and exits 1 if the node stopped answering or kept a NaN."""
import math
import sys

import rospy
from dynamic_reconfigure.msg import Config, DoubleParameter
from dynamic_reconfigure.srv import Reconfigure, ReconfigureRequest
from std_srvs.srv import Trigger


def main():
    rospy.init_node("soak_faults", anonymous=True)
    ok = True
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
    sys.exit(main())
