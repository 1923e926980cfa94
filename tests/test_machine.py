"""harv_jax.machine: the CPU's model name and SIMD level, read from /proc/cpuinfo's text."""

from __future__ import annotations

from harv_jax import machine

CPUINFO = """processor\t: 0
vendor_id\t: AuthenticAMD
model name\t: AMD EPYC 9B14 96-Core Processor
flags\t\t: fpu vme sse sse2 avx avx2 fma bmi2
"""


def test_reads_the_model_name_and_the_widest_simd_level(monkeypatch):
    monkeypatch.setattr(machine, "_cpuinfo", lambda: CPUINFO)
    assert machine.cpu_model() == "AMD EPYC 9B14 96-Core Processor"
    assert machine.simd_level() == "avx2"
    monkeypatch.setattr(machine, "_cpuinfo", lambda: CPUINFO.replace("bmi2", "bmi2 avx512f avx512fp16"))
    assert machine.simd_level() == "avx512f"


def test_without_cpuinfo_it_falls_back(monkeypatch):
    monkeypatch.setattr(machine, "_cpuinfo", lambda: "")
    monkeypatch.setattr(machine.platform, "processor", lambda: "")
    assert machine.cpu_model() == "unknown" and machine.simd_level() == ""
