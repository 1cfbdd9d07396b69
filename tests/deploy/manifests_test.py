"""Structural checks of deploy/kubernetes/*.yaml and compose.yaml (no cluster here): the
objects issue 9 asks for exist and agree with each other and with lipsyncd's settings."""

import pathlib
import sys
import unittest

import yaml

ROOT = pathlib.Path(sys.argv.pop(1) if len(sys.argv) > 1 else ".").resolve()


def documents(path):
    with open(ROOT / path, encoding="utf-8") as stream:
        return [doc for doc in yaml.safe_load_all(stream) if doc]


class LipsyncdManifests(unittest.TestCase):
    def setUp(self):
        self.objects = {(d["kind"], d["metadata"]["name"]): d for d in documents("deploy/kubernetes/lipsyncd.yaml")}
        self.deployment = self.objects[("Deployment", "lipsyncd")]
        self.pod = self.deployment["spec"]["template"]["spec"]
        self.container = self.pod["containers"][0]
        self.env = {e["name"]: e for e in self.container["env"]}

    def test_every_object_the_issue_asks_for_is_there(self):
        for key in [("Deployment", "lipsyncd"), ("Service", "lipsyncd"), ("Service", "lipsyncd-replicas"),
                    ("PodDisruptionBudget", "lipsyncd"), ("HorizontalPodAutoscaler", "lipsyncd")]:
            self.assertIn(key, self.objects)

    def test_services_and_budget_select_the_pods(self):
        labels = self.deployment["spec"]["template"]["metadata"]["labels"]
        for key in [("Service", "lipsyncd"), ("Service", "lipsyncd-replicas")]:
            self.assertLessEqual(self.objects[key]["spec"]["selector"].items(), labels.items(), key)
        budget = self.objects[("PodDisruptionBudget", "lipsyncd")]["spec"]["selector"]["matchLabels"]
        self.assertLessEqual(budget.items(), labels.items())
        self.assertEqual(self.objects[("Service", "lipsyncd-replicas")]["spec"]["clusterIP"], "None")

    def test_probes_use_the_grpc_health_protocol_on_the_listening_port(self):
        port = int(self.env["LIPSYNCD_LISTEN"]["value"].rsplit(":", 1)[1])
        self.assertEqual(self.container["ports"][0]["containerPort"], port)
        for probe in ("readinessProbe", "livenessProbe"):
            self.assertEqual(self.container[probe]["grpc"]["port"], port, probe)

    def test_termination_grace_outlasts_the_drain(self):
        drain_ms = int(self.env["LIPSYNCD_DRAIN_DEADLINE_MS"]["value"])
        self.assertGreater(self.pod["terminationGracePeriodSeconds"] * 1000, drain_ms)

    def test_pods_run_as_non_root_with_resource_requests_and_a_replica_name(self):
        self.assertTrue(self.pod["securityContext"]["runAsNonRoot"])
        self.assertNotEqual(self.pod["securityContext"]["runAsUser"], 0)
        self.assertIn("cpu", self.container["resources"]["requests"])
        self.assertEqual(self.env["LIPSYNCD_REPLICA_NAME"]["valueFrom"]["fieldRef"]["fieldPath"], "metadata.name")

    def test_the_autoscaler_scales_the_deployment_on_cpu(self):
        hpa = self.objects[("HorizontalPodAutoscaler", "lipsyncd")]["spec"]
        self.assertEqual(hpa["scaleTargetRef"]["name"], "lipsyncd")
        self.assertEqual(hpa["metrics"][0]["resource"]["name"], "cpu")
        self.assertGreaterEqual(hpa["minReplicas"], 2)

    def test_every_environment_variable_is_a_lipsyncd_setting(self):
        help_flags = {"LISTEN", "DRAIN_DEADLINE_MS", "REPLICA_NAME", "MAX_STREAMS", "LOG_LEVEL"}
        for name in self.env:
            self.assertTrue(name.startswith("LIPSYNCD_") and name[9:] in help_flags, name)


class BalancerManifests(unittest.TestCase):
    def test_the_balancer_hashes_on_the_session_header_and_reaches_the_headless_service(self):
        objects = {(d["kind"], d["metadata"]["name"]): d for d in documents("deploy/kubernetes/balancer.yaml")}
        conf = objects[("ConfigMap", "lipsync-balancer")]["data"]["lipsyncd.conf"]
        self.assertIn("$http_x_lipsync_session", conf)
        self.assertIn("hash $lipsync_route consistent;", conf)
        self.assertIn("server lipsyncd-replicas:50051", conf)
        self.assertIn("grpc_pass grpc://lipsyncd;", conf)


class Compose(unittest.TestCase):
    def test_three_replicas_behind_nginx(self):
        compose = documents("compose.yaml")[0]["services"]
        replicas = [name for name, service in compose.items() if service.get("build") or "lipsyncd" in str(service.get("image", ""))]
        self.assertEqual(len(replicas), 3, replicas)
        balancer = compose["balancer"]
        self.assertEqual(set(balancer["depends_on"]), set(replicas))
        for name in replicas:
            self.assertEqual(compose[name]["environment"]["LIPSYNCD_REPLICA_NAME"], name)


if __name__ == "__main__":
    unittest.main()
