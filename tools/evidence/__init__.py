"""tools.evidence: the evidence tools, one question each (docs/architecture.md section 1).

- ``margins``      how much gain, phase and delay can the loop lose?   python -m tools.evidence.margins
- ``envelope``     where across Mach x altitude does the spec hold with the fixed gains?
                                                                       python -m tools.evidence.envelope
- ``coordination`` what does each coordination factor do?             python -m tools.evidence.coordination
- ``montecarlo``   how often does the law meet the spec, and beat the uncoordinated law, under
                   the paper's dispersions?                            python -m tools.evidence.montecarlo
- ``mutate``       does a wrong law fail the law's tests?              python -m tools.evidence.mutate
- ``report``       do the README's and the docs' tables say what the runs measured?
                                                                       python -m tools.evidence.report
- ``dispersions/`` the campaigns' dispersion files and the paper's spec (TOML).

Each stands on the SITL harness (tools.sitl); none imports a command outside tools.evidence.
"""
