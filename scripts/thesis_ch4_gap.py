#!/usr/bin/env python3
"""Print, step by step, where the topology energies differ from the thesis' Table 4-5 (and the
cost offset of eq 4-4): the tables of docs/thesis.md, "Chapter 4 against Table 4-5".

    PYTHONPATH=. python scripts/thesis_ch4_gap.py
"""
from bev_mdo.studies import thesis_ch4 as t4


def main() -> None:
    tops = t4.TOPOLOGIES
    print("Energy, combined Artemis, kWh/100 km (each step changes one thing against the baseline)\n")
    print("| step | what changes | " + " | ".join(tops) + " | DM-DA / SM-SA | IWM-SA / SM-SA | IWM-DA / SM-SA |")
    print("|---" * (5 + len(tops)) + "|")
    th = t4.THESIS_ENERGY
    print("| Table 4-5 | thesis | " + " | ".join(f"{th[t]:.2f}" for t in tops) + " | "
          + " | ".join(f"{th[t] / th['SM-SA'] - 1:+.1%}" for t in tops[1:]) + " |")
    rows = t4.gap_table()
    for r in rows:
        print(f"| `{r['key']}` | {r['label']} | " + " | ".join(f"{r[t]:.2f}" for t in tops) + " | "
              + " | ".join(f"{r[t] / r['SM-SA'] - 1:+.1%}" for t in tops[1:]) + " |")
    for key in ("ch5_30", "baseline"):  # how far each topology is from the thesis
        r = next(r for r in rows if r["key"] == key)
        print(f"| `{key}` / Table 4-5 | | " + " | ".join(f"{r[t] / th[t] - 1:+.1%}" for t in tops) + " | | | |")
    print(f"\nTable 3-2 row 1 (same SM-SA design, ch.3): {t4.TABLE_3_2_COMBINED_KWH} kWh over Table 2-2's "
          f"combined distance = {t4.table_3_2_combined_kwh_per_100km():.2f} kWh/100 km")
    print(f"Constant auxiliary load that would close the SM-SA gap: {t4.aux_power_to_close_w():.0f} W")
    a, b = t4.equal_split_identity()
    print(f"Equal-split identity on the NEDC (motor energy, Wh): DM-DA 50/50 {a:.6f}, SM-SA at DM-DA mass {b:.6f}")
    print("\nSM-SA benchmark per Artemis part beside Table 3-2 row 1, kWh\n")
    print("| part | km ours / Table 2-2 | baseline | `ch5_30` | Table 3-2 |")
    print("|---|---|---|---|---|")
    for r in t4.segment_table():
        print(f"| {r['cycle']} | {r['km']:.2f} / {r['thesis_km']:.2f} | {r['kwh']:.3f} | {r['kwh_ch5_30']:.3f} | "
              f"{r['thesis_kwh']:.2f} |")
    print("\nCost at the Table 4-4 designs, US$\n")
    print("| topology | motors, eq 2-21 | eq 4-4 | Table 4-5 | eq 4-4 - Table 4-5 | implied pack $ "
          "| implied pack kWh |")
    print("|---|---|---|---|---|---|---|")
    for r in t4.cost_table():
        print(f"| {r['topology']} | {r['motors_usd']:.1f} | {r['eq_4_4_usd']:.1f} | {r['thesis_usd']:.1f} | "
              f"{r['offset_usd']:+.1f} | {r['implied_pack_usd']:.1f} | {r['implied_pack_kwh']:.3f} |")


if __name__ == "__main__":
    main()
