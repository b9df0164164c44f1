// Fluted control knob: a grip with ten flutes, a skirt and a bore. About 44 x 44 x 24 mm.
$fn = 48;

difference() {
  union() {
    cylinder(h = 4, d = 44);                          // skirt
    cylinder(h = 20, d = 34);                         // grip
    translate([0, 0, 20]) cylinder(h = 4, d1 = 34, d2 = 26);  // chamfered top
  }
  for (a = [0:36:359]) rotate([0, 0, a]) translate([18.5, 0, 5]) cylinder(h = 30, d = 7);  // flutes
  translate([0, 0, -1]) cylinder(h = 16, d = 6);      // shaft bore
  translate([0, 0, 22.5]) cube([2, 20, 4], center = true);   // pointer groove
}
