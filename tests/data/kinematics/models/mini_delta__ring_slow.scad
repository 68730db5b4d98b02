difference() { cylinder(r=54.61, h=1.2, $fn=360); translate([0, 0, -1]) cylinder(r=42.61, h=5, $fn=360); }
