// T-nut for a machine-table slot: a T profile with chamfered flange ends and a tapped
// hole (drawn plain). About 40 x 30 x 18 mm.
$fn = 40;

difference() {
  union() {
    translate([-20, -15, 0]) cube([40, 30, 7]);        // flange
    translate([-20, -8, 7]) cube([40, 16, 11]);       // stem
  }
  translate([0, 0, -1]) cylinder(h = 30, d = 10);     // M12-size hole
  for (s = [-1, 1])                                    // chamfers on the flange ends
    translate([s * 20, 0, 7]) rotate([0, 45, 0]) cube([5, 40, 5], center = true);
}
