// gelgrip dashboard: axis ticks and their labels, shared by every chart of the page.
"use strict";
